"""evaluate stage: render a view with the probes and with the reference, compare (DESIGN.md
"Evaluation protocol"; docs/evaluate.md)."""

from ._attribute import diffuse_contributions as diffuse_contributions
from ._attribute import glossy_contributions as glossy_contributions
from ._config import EvalConfig as EvalConfig
from ._config import check_eval_memory as check_eval_memory
from ._decompose import bootstrap_ci as bootstrap_ci
from ._decompose import glossy_terms as glossy_terms
from ._decompose import hit_agreement as hit_agreement
from ._decompose import relative_mse as relative_mse
from ._evaluate import EVAL_COMPONENTS as EVAL_COMPONENTS
from ._evaluate import EvalResult as EvalResult
from ._evaluate import evaluate as evaluate
from ._evaluate import memory_bytes as memory_bytes
from ._evaluate import score as score
from ._scene_checks import check_views_and_lights as check_views_and_lights
from ._steps import CrnReference as CrnReference
from ._steps import PerfectTrace as PerfectTrace
from ._steps import PrimarySamples as PrimarySamples
from ._steps import ProbeShading as ProbeShading
from ._steps import ReferenceImages as ReferenceImages
from ._steps import crn_reference as crn_reference
from ._steps import perfect_trace as perfect_trace
from ._steps import render_reference as render_reference
from ._steps import sample_primary as sample_primary
from ._steps import shade_probes as shade_probes
from ._write import evaluation_bytes as evaluation_bytes
from ._write import false_colour as false_colour
from ._write import write_evaluation as write_evaluation
