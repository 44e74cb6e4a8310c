"""Where a probe may go and how many fit: valid space (clearance, relocation out of geometry:
``_valid``), placement regions (``_region``), the space reachable from the views (``_reach``), the exact
budget and memory bounds (``_budget``) and grid layouts (``_grid``).

This ``__init__`` is the group's face for the rest of ``placement``."""

from ._budget import check_probe_count as check_probe_count
from ._budget import count_for_memory as count_for_memory
from ._budget import fit_to_budget as fit_to_budget
from ._budget import parse_bytes as parse_bytes
from ._grid import grid_dims as grid_dims
from ._grid import uniform_grid as uniform_grid
from ._reach import ReachableSpace as ReachableSpace
from ._reach import reachable_space as reachable_space
from ._reach import view_positions as view_positions
from ._region import Region as Region
from ._valid import ValidSpace as ValidSpace
from ._valid import default_clearance as default_clearance
from ._valid import fibonacci_directions as fibonacci_directions
from ._valid import make_valid as make_valid
from ._valid import relocate_out as relocate_out
from ._valid import valid_candidates as valid_candidates
