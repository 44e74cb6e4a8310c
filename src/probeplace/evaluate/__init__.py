"""evaluate stage: render a view with the probes and with the reference, compare (DESIGN.md
"Evaluation protocol"; docs/evaluate.md)."""

from ._evaluate import EVAL_COMPONENTS as EVAL_COMPONENTS
from ._evaluate import EvalConfig as EvalConfig
from ._evaluate import EvalResult as EvalResult
from ._evaluate import evaluate as evaluate
from ._evaluate import memory_bytes as memory_bytes
from ._write import false_colour as false_colour
from ._write import write_evaluation as write_evaluation
