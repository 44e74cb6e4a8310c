"""experiment stage (see DESIGN.md): config schemas, ``run(cfg) -> RunResult``, atomic results.

Imports neither Hydra nor OmegaConf: ``experiments/run.py`` is the Hydra edge and passes its config down."""

from ..placement import METHODS as PLACERS  # noqa: F401 (public: the placement registry's names)
from ._report import load_runs as load_runs
from ._report import make_report as make_report
from ._report import pareto_front as pareto_front
from ._report_data import seed_paired_ratio as seed_paired_ratio
from ._results import DONE as DONE
from ._results import is_complete as is_complete
from ._results import iter_runs as iter_runs
from ._run import EvaluationUnavailable as EvaluationUnavailable
from ._run import RunResult as RunResult
from ._run import check_scenes as check_scenes
from ._run import failures as failures
from ._run import load_experiment_scene as load_experiment_scene
from ._run import run as run
from ._run import run_dir as run_dir
from ._run import run_name as run_name
from ._schema import BakeStage as BakeStage
from ._schema import EvalStage as EvalStage
from ._schema import ExperimentConfig as ExperimentConfig
from ._schema import ExportConfig as ExportConfig
from ._schema import LightFieldStage as LightFieldStage
from ._schema import PlacerConfig as PlacerConfig
from ._schema import RefinerConfig as RefinerConfig
from ._schema import SceneStage as SceneStage
from ._schema import TracerConfig as TracerConfig
from ._schema import bake_config as bake_config
from ._schema import bake_values as bake_values
from ._schema import eval_config as eval_config
from ._schema import eval_values as eval_values
from ._schema import place_values as place_values
from ._schema import to_config as to_config
from ._schema import trace_values as trace_values
from ._schema import validate as validate
