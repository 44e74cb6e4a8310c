"""What a known external scene's file cannot say: lights, sky, units and good views, keyed by file stem.

The values for the two scenes of ``../shared/scenes`` follow that folder's README (views, units). The
Sponza sun was chosen by casting rays against the file (see ``tests/scene/test_load_files.py``,
``test_sponza_sun_reaches_ground_floor``): the roof opening over the court is a slot about 24 m long
(x ∈ [−13.5, 10.5]) and only ~5 m wide (z ∈ [−3, 1.5]) above a ~19 m-deep court, so only a high sun
tilted along the long (X) axis reaches the ground floor. With azimuth 170° (toward −X, slightly +Z)
and elevation 65°, about 12% of the whole ground floor (most of the court's floor) is sunlit, with the
galleries' shadows across it; at 45° elevation or with the sun across the slot (azimuth 90°) almost
none is.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from .._core import Camera, Sun
from ._build import make_camera
from ._sky import DAYLIGHT_SKY_RADIANCE, sun_direction, sun_from_irradiance


@dataclasses.dataclass(frozen=True)
class KnownScene:
    """Extra facts about an external scene file.

    Attributes:
        views: replace the file's own cameras when non-empty.
        sun: factory for the sun (``None``: no sun).
        sky_radiance: constant sky radiance, linear RGB.
        unit_m: metres per file unit (overrides glTF's "metres" where the file is in other units).
    """

    views: Callable[[], tuple[Camera, ...]]
    sun: Callable[[], Sun] | None = None
    sky_radiance: tuple[float, float, float] = (0.0, 0.0, 0.0)
    unit_m: float | None = None


def _sponza_views() -> tuple[Camera, ...]:
    return (
        make_camera((15.46, 4.39, 0.45), (5.69, 6.37, -0.33), 45.0, "CameraMain"),
        make_camera((15.02, 11.96, 3.65), (5.33, 12.38, 6.09), 45.0, "CameraBalcony"),
        make_camera((-15.05, 5.87, 5.79), (-5.17, 5.87, 4.22), 45.0, "CameraAlcove"),
        make_camera((-12.0, 5.7, 0.0), (12.0, 7.5, 0.0), 60.0, "atrium"),
    )


def _cornell_views() -> tuple[Camera, ...]:
    return (
        make_camera((278.0, 273.0, -800.0), (278.0, 273.0, -799.0), 39.3, "front"),
        make_camera((278.0, 500.0, 30.0), (278.0, 80.0, 420.0), 65.0, "interior"),
    )


def _sponza_sun() -> Sun:
    return sun_from_irradiance(sun_direction(azimuth_deg=170.0, elevation_deg=65.0))


#: Known external scenes, keyed by file stem.
KNOWN_SCENES: dict[str, KnownScene] = {
    "crytek_sponza": KnownScene(
        views=_sponza_views, sun=_sponza_sun, sky_radiance=DAYLIGHT_SKY_RADIANCE, unit_m=1.0
    ),
    "cornell_box": KnownScene(views=_cornell_views, unit_m=0.001),  # the file is in millimetres
}
