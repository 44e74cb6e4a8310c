"""Placement stage (DESIGN.md): fitness (Wang 2019 Eq. 1–2, union coverage), skeleton seeds, refiners,
automatic budget, and ``place``. See docs/placement.md."""

from ._auto import AutoResult as AutoResult
from ._auto import auto_budget as auto_budget
from ._auto import reaches_target as reaches_target
from ._binary import CoverageDetail as CoverageDetail
from ._binary import binary_coverage as binary_coverage
from ._binary import binary_visibility as binary_visibility
from ._binary import coverage_counts as coverage_counts
from ._binary import wang_fitness_binary as wang_fitness_binary
from ._budget import check_probe_count as check_probe_count
from ._budget import count_for_memory as count_for_memory
from ._budget import parse_bytes as parse_bytes
from ._field import tighten_sdf as tighten_sdf
from ._finish import CoverageContext as CoverageContext
from ._finish import coverage_context as coverage_context
from ._finish import coverage_detail as coverage_detail
from ._fitness import COVERAGE_RULES as COVERAGE_RULES
from ._fitness import FitnessConfig as FitnessConfig
from ._fitness import PlacementProblem as PlacementProblem
from ._fitness import coverage_objective as coverage_objective
from ._fitness import make_problem as make_problem
from ._fitness import probe_clearance as probe_clearance
from ._fitness import probe_column as probe_column
from ._fitness import shading_objective as shading_objective
from ._fitness import wang_fitness as wang_fitness
from ._fitness import witness_positions as witness_positions
from ._grid import grid_dims as grid_dims
from ._grid import uniform_grid as uniform_grid
from ._place import place as place
from ._place import save_top_view as save_top_view
from ._place import smallest_full_grid as smallest_full_grid
from ._refine import OBJECTIVES as OBJECTIVES
from ._refine import REFINERS as REFINERS
from ._refine import AbstractRefiner as AbstractRefiner
from ._refine import GibbsRefiner as GibbsRefiner
from ._refine import RefineResult as RefineResult
from ._refine import get_refiner as get_refiner
from ._refine import objective_fn as objective_fn
from ._refine import stochastic_direction as stochastic_direction
from ._region import Region as Region
from ._registry import PlacementMethod as PlacementMethod
from ._registry import PlaceRequest as PlaceRequest
from ._registry import PlaceResult as PlaceResult
from ._registry import get_method as get_method
from ._registry import method_names as method_names
from ._registry import method_options as method_options
from ._registry import reference_methods as reference_methods
from ._registry import register_method as register_method
from ._seeds import medial_axis_seeds as medial_axis_seeds
from ._seeds import shrink_balls as shrink_balls
from ._seeds import skeleton_seeds as skeleton_seeds
from ._valid import ValidSpace as ValidSpace
from ._valid import default_clearance as default_clearance
from ._valid import fibonacci_directions as fibonacci_directions
from ._valid import make_valid as make_valid

# --- baselines (registered on import) ---
# isort: split
from ._baselines import GridOptions as GridOptions
from ._baselines import LodGridOptions as LodGridOptions
from ._baselines import VardisOptions as VardisOptions
from ._lod_grid import LODGrid as LODGrid
from ._lod_grid import lod_probe_grid as lod_probe_grid
from ._uniform import INSIDE_CHOICES as INSIDE_CHOICES
from ._uniform import UniformGridResult as UniformGridResult
from ._uniform import uniform_probe_grid as uniform_probe_grid
from ._vardis import ERROR_MODES as ERROR_MODES
from ._vardis import VardisResult as VardisResult
from ._vardis import dense_probe_sh as dense_probe_sh
from ._vardis import error_features as error_features
from ._vardis import evaluation_points as evaluation_points
from ._vardis import leave_one_out_scores as leave_one_out_scores
from ._vardis import poisson_disk_probes as poisson_disk_probes
from ._vardis import vardis_simplify as vardis_simplify

# isort: split
#: The built-in methods, in registration order (``method_names()`` also lists methods registered later).
METHODS = method_names()
#: Methods that lay a lattice anchored to the scene's box (their ``shift`` option moves it).
BASELINE_METHODS = tuple(m for m in METHODS if get_method(m).lattice)
