"""The daylight constants (plain Python, no JAX): the sidecar parser reads them without loading the scene
builder; :mod:`._sky` builds suns from them."""

from __future__ import annotations

#: Real sun's angular radius, radians (0.53° apparent diameter).
SUN_ANGULAR_RADIUS = 0.00465
#: Irradiance (linear RGB) from the sun on a surface facing it; warm white.
DAYLIGHT_SUN_IRRADIANCE = (8.0, 7.5, 6.6)
#: Constant sky radiance (linear RGB); bluish.
DAYLIGHT_SKY_RADIANCE = (0.38, 0.46, 0.62)
