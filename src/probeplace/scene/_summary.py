"""What a loaded scene resolved to — lights, cameras, units, bounds, triangles — as plain data
(``probeplace scenes -v NAME`` prints it; a run records it in ``inputs.json`` as ``scene_loaded``).

Every vector is in the loaded scene's frame (+Y up, scene units): a Z-up file's sun and cameras appear
turned, a ``scale_to_metres`` scene's cameras scaled.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .._core import Scene
from .light import sun_from_irradiance


def _vec(x) -> list[float]:
    return [float(v) for v in np.asarray(x, np.float64).ravel()]


def sun_summary(sun) -> dict[str, Any] | None:
    """Direction (toward the sun), its azimuth (from +X toward +Z) and elevation in degrees, the disk's
    radiance, the irradiance it gives on a surface facing it, and its angular diameter."""
    if sun is None:
        return None
    d = np.asarray(sun.direction, np.float64)
    d = d / np.linalg.norm(d)
    r = float(np.asarray(sun.angular_radius))
    radiance = np.asarray(sun.radiance, np.float64)
    per_unit = np.asarray(sun_from_irradiance(d, (1.0, 1.0, 1.0), r).radiance, np.float64)  # L for E = 1
    return {
        "direction": _vec(d),
        "azimuth_deg": math.degrees(math.atan2(d[2], d[0])),
        "elevation_deg": math.degrees(math.asin(max(-1.0, min(1.0, d[1])))),
        "radiance": _vec(radiance),
        "irradiance": _vec(radiance / per_unit),
        "angular_diameter_deg": math.degrees(2.0 * r),
    }


def scene_summary(scene: Scene) -> dict[str, Any]:
    """The scene's ``name``, ``unit_m``, ``bounds`` (lo, hi), ``triangles``, ``sun``
    (:func:`sun_summary`, or None), ``sky`` (radiance, or None when black), ``emitters`` (per emissive
    material: radiance and triangle count) and ``cameras`` (per view: position, look_at, up, vertical fov)."""
    sky = np.asarray(scene.sky_radiance, np.float64)
    mats = scene.materials
    emission = np.asarray(mats.emission, np.float64)
    tri_material = np.asarray(scene.tri_material)
    counts = np.bincount(tri_material, minlength=len(mats.names))
    emitters = {
        name: {"radiance": _vec(emission[i]), "triangles": int(counts[i])}
        for i, name in enumerate(mats.names)
        if emission[i].max() > 0 and counts[i] > 0
    }
    cameras = {
        c.name: {
            "position": _vec(c.position),
            "look_at": _vec(c.look_at),
            "up": _vec(c.up),
            "fov_deg": float(np.asarray(c.fov_y_deg)),
        }
        for c in scene.views
    }
    bounds = np.asarray(scene.bounds, np.float64)
    return {
        "name": scene.name,
        "unit_m": float(scene.unit_m),
        "bounds": [_vec(bounds[0]), _vec(bounds[1])],
        "triangles": int(np.asarray(scene.faces).shape[0]),
        "sun": sun_summary(scene.sun),
        "sky": _vec(sky) if sky.max() > 0 else None,
        "emitters": emitters,
        "cameras": cameras,
    }
