"""What a known external scene's file cannot say (lights, sky, units, good views), keyed by file stem, as
sidecar mappings: the same mechanism as a user's ``<stem>.probeplace.yaml``.

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

from typing import Any

# Each entry is a sidecar mapping (docs/scenes.md, "Sidecar config"): the layer between the file and the
# user's sidecar, so a user's room.probeplace.yaml overrides it key by key like any other layer.
_SPONZA: dict[str, Any] = {
    "units": 1.0,
    "sun": {"azimuth": 170.0, "elevation": 65.0},  # daylight irradiance, the real sun's size
    "sky": "daylight",
    "keep_file_cameras": False,
    "cameras": {
        "CameraMain": {"position": [15.46, 4.39, 0.45], "look_at": [5.69, 6.37, -0.33], "fov": 45.0},
        "CameraBalcony": {"position": [15.02, 11.96, 3.65], "look_at": [5.33, 12.38, 6.09], "fov": 45.0},
        "CameraAlcove": {"position": [-15.05, 5.87, 5.79], "look_at": [-5.17, 5.87, 4.22], "fov": 45.0},
        "atrium": {"position": [-12.0, 5.7, 0.0], "look_at": [12.0, 7.5, 0.0], "fov": 60.0},
    },
}
_CORNELL: dict[str, Any] = {
    "units": "mm",  # the file is in millimetres
    "keep_file_cameras": False,
    "cameras": {
        "front": {"position": [278.0, 273.0, -800.0], "look_at": [278.0, 273.0, -799.0], "fov": 39.3},
        "interior": {"position": [278.0, 500.0, 30.0], "look_at": [278.0, 80.0, 420.0], "fov": 65.0},
    },
}

#: Known external scenes, keyed by file stem: sidecar mappings applied under the user's own sidecar.
KNOWN_SCENES: dict[str, dict[str, Any]] = {"crytek_sponza": _SPONZA, "cornell_box": _CORNELL}
