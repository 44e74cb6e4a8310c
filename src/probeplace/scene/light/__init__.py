"""Daylight: the constants (``_daylight``, plain Python, read by the sidecar parser) and the sun and sky
built from them (``_sky``: a sun by the irradiance it delivers, a sun direction by azimuth and elevation).

This ``__init__`` is the group's face for the rest of ``scene``. The constants load eagerly; the ``_sky``
names on first use (PEP 562 ``__getattr__``): they import JAX, and ``probeplace scenes`` must not."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..._core._lazy import lazy_exports
from ._daylight import DAYLIGHT_SKY_RADIANCE as DAYLIGHT_SKY_RADIANCE
from ._daylight import DAYLIGHT_SUN_IRRADIANCE as DAYLIGHT_SUN_IRRADIANCE
from ._daylight import SUN_ANGULAR_RADIUS as SUN_ANGULAR_RADIUS

# name -> the private module defining it (it imports JAX)
_LAZY = dict.fromkeys(("sun_direction", "sun_from_irradiance"), "_sky")

if TYPE_CHECKING:  # what static checkers and IDEs see; __getattr__ gives the same at run time
    from ._sky import sun_direction as sun_direction
    from ._sky import sun_from_irradiance as sun_from_irradiance


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals(), [*_LAZY])
