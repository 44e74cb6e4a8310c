"""Placement stage (DESIGN.md; docs/placement.md): ``place`` and the method registry, grouped by role:

* ``_place``, ``_registry``, ``_finish``: ``place()``, the registry (``PlaceRequest`` / ``PlaceResult``) and
  the common end every method shares (valid space, exact budget, coverage, refinement);
* ``skeleton/``: Wang 2019's seeds and automatic budget; ``baselines/``: the grids and Vardis 2021;
* ``refine/``: the refiners; ``fitness/``: Eq. 1–2, union and binary coverage;
* ``space/``: valid space, regions, reach, budgets and grid layouts.

Each group's ``__init__`` is its face for the rest of the stage; this one is the stage's."""

from ._finish import CoverageContext as CoverageContext
from ._finish import coverage_context as coverage_context
from ._finish import coverage_detail as coverage_detail
from ._finish import result_coverage_detail as result_coverage_detail
from ._place import place as place
from ._place import save_top_view as save_top_view
from ._place import smallest_full_grid as smallest_full_grid
from ._registry import LIBRARY_ONLY as LIBRARY_ONLY
from ._registry import PlacementMethod as PlacementMethod
from ._registry import PlaceRequest as PlaceRequest
from ._registry import PlaceResult as PlaceResult
from ._registry import get_method as get_method
from ._registry import method_names as method_names
from ._registry import method_options as method_options
from ._registry import reference_methods as reference_methods
from ._registry import register_method as register_method
from .fitness import COVERAGE_RULES as COVERAGE_RULES
from .fitness import CoverageDetail as CoverageDetail
from .fitness import FitnessConfig as FitnessConfig
from .fitness import PlacementProblem as PlacementProblem
from .fitness import binary_coverage as binary_coverage
from .fitness import binary_visibility as binary_visibility
from .fitness import coverage_counts as coverage_counts
from .fitness import coverage_objective as coverage_objective
from .fitness import make_problem as make_problem
from .fitness import probe_clearance as probe_clearance
from .fitness import probe_column as probe_column
from .fitness import shading_objective as shading_objective
from .fitness import tighten_sdf as tighten_sdf
from .fitness import wang_fitness as wang_fitness
from .fitness import wang_fitness_binary as wang_fitness_binary
from .fitness import witness_positions as witness_positions
from .refine import OBJECTIVES as OBJECTIVES
from .refine import REFINERS as REFINERS
from .refine import AbstractRefiner as AbstractRefiner
from .refine import GibbsRefiner as GibbsRefiner
from .refine import RefineResult as RefineResult
from .refine import get_refiner as get_refiner
from .refine import objective_fn as objective_fn
from .refine import stochastic_direction as stochastic_direction
from .skeleton import AutoResult as AutoResult
from .skeleton import auto_budget as auto_budget
from .skeleton import medial_axis_seeds as medial_axis_seeds
from .skeleton import reaches_target as reaches_target
from .skeleton import shrink_balls as shrink_balls
from .skeleton import skeleton_seeds as skeleton_seeds
from .space import Region as Region
from .space import ValidSpace as ValidSpace
from .space import check_probe_count as check_probe_count
from .space import count_for_memory as count_for_memory
from .space import default_clearance as default_clearance
from .space import fibonacci_directions as fibonacci_directions
from .space import grid_dims as grid_dims
from .space import make_valid as make_valid
from .space import parse_bytes as parse_bytes
from .space import uniform_grid as uniform_grid

# --- baselines (registered on import) ---
# isort: split
from .baselines import ERROR_MODES as ERROR_MODES
from .baselines import INSIDE_CHOICES as INSIDE_CHOICES
from .baselines import GridOptions as GridOptions
from .baselines import LODGrid as LODGrid
from .baselines import LodGridOptions as LodGridOptions
from .baselines import UniformGridResult as UniformGridResult
from .baselines import VardisOptions as VardisOptions
from .baselines import VardisResult as VardisResult
from .baselines import dense_probe_sh as dense_probe_sh
from .baselines import error_features as error_features
from .baselines import evaluation_points as evaluation_points
from .baselines import leave_one_out_scores as leave_one_out_scores
from .baselines import lod_probe_grid as lod_probe_grid
from .baselines import poisson_disk_probes as poisson_disk_probes
from .baselines import uniform_probe_grid as uniform_probe_grid
from .baselines import vardis_simplify as vardis_simplify

# isort: split
#: The built-in methods, in registration order (``method_names()`` also lists methods registered later).
METHODS = method_names()
#: Methods that lay a lattice anchored to the scene's box (their ``shift`` option moves it).
BASELINE_METHODS = tuple(m for m in METHODS if get_method(m).lattice)
