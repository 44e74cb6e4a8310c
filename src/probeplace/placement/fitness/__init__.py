"""What a placement is scored by: Wang 2019 Eq. 1–2 and the union coverage (``_fitness``; the
soft SDF visibility of ``_field``) and the binary, exactly cast coverage every method reports (``_binary``).

This ``__init__`` is the group's face for the rest of ``placement``."""

from ._binary import CoverageDetail as CoverageDetail
from ._binary import binary_coverage as binary_coverage
from ._binary import binary_visibility as binary_visibility
from ._binary import coverage_counts as coverage_counts
from ._binary import wang_fitness_binary as wang_fitness_binary
from ._field import tighten_sdf as tighten_sdf
from ._fitness import COVERAGE_RULES as COVERAGE_RULES
from ._fitness import FitnessConfig as FitnessConfig
from ._fitness import PlacementProblem as PlacementProblem
from ._fitness import coverage_from_columns as coverage_from_columns
from ._fitness import coverage_objective as coverage_objective
from ._fitness import dynamic_float as dynamic_float
from ._fitness import make_problem as make_problem
from ._fitness import probe_clearance as probe_clearance
from ._fitness import probe_column as probe_column
from ._fitness import probe_distance_term as probe_distance_term
from ._fitness import shading_column as shading_column
from ._fitness import shading_from_columns as shading_from_columns
from ._fitness import shading_objective as shading_objective
from ._fitness import wang_fitness as wang_fitness
from ._fitness import wang_from_columns as wang_from_columns
from ._fitness import witness_positions as witness_positions
