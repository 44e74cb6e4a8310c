"""probeplace: light-probe placement, light-field probe baking and evaluation in JAX."""

from ._core import Camera as Camera
from ._core import Hit as Hit
from ._core import Materials as Materials
from ._core import ProbeSet as ProbeSet
from ._core import Scene as Scene
from ._core import Sun as Sun

__version__ = "0.1.0"
