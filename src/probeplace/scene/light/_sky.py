"""Sun and sky for outdoor scenes, specified by the irradiance they deliver (easier to reason about).

Radiance is linear RGB "up to a common scale" (see :mod:`probeplace._core`). The outdoor scenes share
one daylight setting: a sun that delivers :data:`DAYLIGHT_SUN_IRRADIANCE` on a surface facing it and a
constant sky of radiance :data:`DAYLIGHT_SKY_RADIANCE`, so a horizontal surface under an open sky
receives π·L_sky ≈ 1.5 from the sky (Lambertian cosine integral) and E_sun·sin(elevation) from the sun:
about one part skylight in five for a sun 40–60° high, the usual clear-sky share.
"""

from __future__ import annotations

import numpy as np

from ..._core import Sun
from .._build import make_sun
from .._primitives import Vec3Like
from ._daylight import DAYLIGHT_SKY_RADIANCE as DAYLIGHT_SKY_RADIANCE
from ._daylight import DAYLIGHT_SUN_IRRADIANCE as DAYLIGHT_SUN_IRRADIANCE
from ._daylight import SUN_ANGULAR_RADIUS as SUN_ANGULAR_RADIUS


def sun_from_irradiance(
    direction: Vec3Like,
    irradiance: Vec3Like = DAYLIGHT_SUN_IRRADIANCE,
    angular_radius: float = SUN_ANGULAR_RADIUS,
) -> Sun:
    """A sun disk whose radiance gives ``irradiance`` on a surface facing it.

    The disk subtends the solid angle Ω = 2π(1 − cos r), so its radiance is L = E / Ω (constant radiance
    over a small cone, cos θ ≈ 1 across it).

    Args:
        direction: vector from the scene toward the sun (world frame, normalised here).
        irradiance: linear RGB irradiance on a surface facing the sun.
        angular_radius: half-angle of the disk, radians.
    """
    omega = 4.0 * np.pi * np.sin(0.5 * angular_radius) ** 2  # 2π(1 − cos r) without cancellation
    radiance = np.asarray(irradiance, np.float64) / omega
    return make_sun(direction, radiance, angular_radius)


def sun_direction(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """Unit vector toward a sun at ``elevation_deg`` above the horizon (+Y up) and ``azimuth_deg``
    measured from +X toward +Z in the horizontal plane."""
    az, el = np.deg2rad(azimuth_deg), np.deg2rad(elevation_deg)
    return np.array([np.cos(el) * np.cos(az), np.sin(el), np.cos(el) * np.sin(az)])
