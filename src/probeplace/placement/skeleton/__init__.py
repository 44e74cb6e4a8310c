"""Wang et al. 2019's own search: skeleton (medial-axis) seeds (``_seeds``) and the automatic
budget that grows the set until the coverage target is reached (``_auto``).

This ``__init__`` is the group's face for the rest of ``placement``."""

from ._auto import AutoResult as AutoResult
from ._auto import auto_budget as auto_budget
from ._auto import reaches_target as reaches_target
from ._seeds import medial_axis_seeds as medial_axis_seeds
from ._seeds import shrink_balls as shrink_balls
from ._seeds import skeleton_seeds as skeleton_seeds
