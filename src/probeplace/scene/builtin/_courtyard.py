"""``courtyard``: a large open square with fine clutter (Wang 2019 §1: "large expanses with densely
populated ... clutter geometry", where a uniform grid over-samples the open space and under-samples the
small things).

A 40 m × 40 m paved square (metres, +Y up) inside low walls with an arcade along the north (+Z) and
east (+X) sides, a fountain in the middle, and about 150 sub-metre objects (crates, posts, benches)
scattered by a fixed low-discrepancy sequence, lit by a sun + sky. Everything is deterministic: the
scatter uses Roberts' R-sequence (pure arithmetic, no random-number generator whose stream could
change between numpy versions).
"""

from __future__ import annotations

import numpy as np

from ..._core import Scene
from .._build import make_camera, materials_from_table
from .._primitives import MeshAssembler, box, cylinder, place, rotation_y
from ..light import DAYLIGHT_SKY_RADIANCE, sun_direction, sun_from_irradiance

_HALF = 20.0  # the square spans [-20, 20] in x and z
_WALL_T = 0.4
_LOW_WALL_H = 1.2
_ARCADE_H = 3.4
_ARCADE_DEPTH = 3.0
_N_CLUTTER = 150
_CLUTTER_EXTENT = 16.0  # clutter stays within [-16, 16]² (clear of the arcades)

_MATERIALS = {  # name: (linear base colour, roughness, metallic)
    "grass": ((0.12, 0.22, 0.06), 0.95, 0.0),
    "paving": ((0.50, 0.47, 0.42), 0.3, 0.0),  # polished stone: glossy indirect over a large area
    "wall": ((0.66, 0.55, 0.42), 0.85, 0.0),
    "roof": ((0.48, 0.20, 0.12), 0.8, 0.0),
    "column": ((0.75, 0.73, 0.68), 0.5, 0.0),
    "water_stone": ((0.35, 0.40, 0.45), 0.2, 0.0),
    "crate": ((0.46, 0.33, 0.18), 0.7, 0.0),
    "post": ((0.10, 0.10, 0.11), 0.4, 1.0),
    "bench": ((0.30, 0.18, 0.10), 0.6, 0.0),
}


def _r_sequence(n: int, dim: int) -> np.ndarray:
    """First n points of Roberts' R_d low-discrepancy sequence in [0, 1)^dim (extremelearning.com.au,
    "The unreasonable effectiveness of quasirandom sequences", 2018)."""
    phi = 2.0
    for _ in range(64):  # fixed point of x = (1 + x)^(1/(dim+1)): the generalised golden ratio
        phi = (1.0 + phi) ** (1.0 / (dim + 1))
    alpha = (1.0 / phi) ** np.arange(1, dim + 1)
    return np.mod(0.5 + np.outer(np.arange(1, n + 1), alpha), 1.0)


def _add_enclosure(a: MeshAssembler) -> None:
    h, t = _HALF, _WALL_T
    a.add(box((-35.0, -0.3, -35.0), (35.0, 0.0, 35.0)), "grass", "ground")
    a.add(box((-h, -0.01, -h), (h, 0.05, h)), "paving", "paving")
    # Low walls on the south (-Z) and west (-X) sides, each with a 4 m gate in the middle.
    for s0, s1 in ((-h - t, -2.0), (2.0, h + t)):
        a.add(box((s0, 0.0, -h - t), (s1, _LOW_WALL_H, -h)), "wall", "low_walls")
        a.add(box((-h - t, 0.0, s0), (-h, _LOW_WALL_H, s1)), "wall", "low_walls")
    # Tall back walls on the north and east sides carry the arcade roofs.
    a.add(box((-h - t, 0.0, h), (h + t, _ARCADE_H + 0.3, h + t)), "wall", "arcade_walls")
    a.add(box((h, 0.0, -h - t), (h + t, _ARCADE_H + 0.3, h + t)), "wall", "arcade_walls")
    d = _ARCADE_DEPTH
    a.add(
        box((-h - t, _ARCADE_H, h - d - 0.3), (h + 0.01, _ARCADE_H + 0.3, h + 0.01)), "roof", "arcade_roofs"
    )
    a.add(
        box((h - d - 0.3, _ARCADE_H, -h - t), (h + 0.01, _ARCADE_H + 0.3, h - d - 0.3 + 0.01)),
        "roof",
        "arcade_roofs",
    )
    # Columns along the open edge of each arcade, every 2.5 m.
    for k in np.arange(-h + 1.25, h - d, 2.5):
        a.add(cylinder((k, 0.04, h - d), 0.2, _ARCADE_H - 0.03, 16), "column", "arcade_columns")
        a.add(cylinder((h - d, 0.04, k), 0.2, _ARCADE_H - 0.03, 16), "column", "arcade_columns")
    a.add(cylinder((h - d, 0.04, h - d), 0.2, _ARCADE_H - 0.03, 16), "column", "arcade_columns")
    # Fountain: a basin, a water-level disc inside it and a central column.
    a.add(cylinder((0.0, 0.04, 0.0), 2.5, 0.55, 48), "wall", "fountain")
    a.add(cylinder((0.0, 0.5, 0.0), 2.2, 0.1, 48), "water_stone", "fountain")
    a.add(cylinder((0.0, 0.55, 0.0), 0.3, 1.8, 24), "column", "fountain")


def _bench(x: float, z: float, angle: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """A 1.4 m bench as three overlapping boxes (seat and two legs), rotated about +Y."""
    parts = [box((-0.7, 0.42, -0.2), (0.7, 0.5, 0.2)), box((-0.65, 0.04, -0.18), (-0.55, 0.43, 0.18))]
    parts.append(box((0.55, 0.04, -0.18), (0.65, 0.43, 0.18)))
    return [place(p, rotation_y(angle), (x, 0.0, z)) for p in parts]


def _add_clutter(a: MeshAssembler) -> int:
    """Scatter crates, posts and benches; returns how many objects were placed."""
    u = _r_sequence(4 * _N_CLUTTER, 4)
    placed: list[tuple[float, float, float]] = [(0.0, 0.0, 3.2)]  # (x, z, keep-out radius): the fountain
    n = 0
    for ux, uz, ukind, usize in u:
        if n == _N_CLUTTER:
            break
        x, z = (2.0 * ux - 1.0) * _CLUTTER_EXTENT, (2.0 * uz - 1.0) * _CLUTTER_EXTENT
        kind = int(ukind * 3)
        radius = (0.5, 0.2, 0.8)[kind]
        if any((x - px) ** 2 + (z - pz) ** 2 < (radius + pr + 0.3) ** 2 for px, pz, pr in placed):
            continue  # keep a 30 cm gap so objects are separate features, not one blob
        angle = 2.0 * np.pi * ((usize * 7.0) % 1.0)
        if kind == 0:  # crate, 0.3–0.8 m
            s = 0.3 + 0.5 * usize
            crate = box((-s / 2, 0.04, -s / 2), (s / 2, 0.04 + s, s / 2))
            a.add(place(crate, rotation_y(angle), (x, 0.0, z)), "crate", "crates")
        elif kind == 1:  # post, 5–12 cm radius, 0.6–1.2 m tall
            a.add(cylinder((x, 0.04, z), 0.05 + 0.07 * usize, 0.6 + 0.6 * usize, 12), "post", "posts")
        else:
            for p in _bench(x, z, angle):
                a.add(p, "bench", "benches")
        placed.append((x, z, radius))
        n += 1
    return n


def courtyard() -> Scene:
    """The built-in courtyard (about 8,000 triangles, 40 m square, sun + sky).

    Views: ``plaza`` (across the square from the south-west corner), ``arcade`` (along the north
    arcade), ``clutter`` (looking down into the scattered objects) and ``fountain``. All are inside the
    scene bounds.
    """
    a = MeshAssembler()
    _add_enclosure(a)
    _add_clutter(a)
    materials = materials_from_table(_MATERIALS, ("base_color", "roughness", "metallic"))
    views = (
        make_camera((-17.0, 1.7, -17.0), (5.0, 0.5, 5.0), 60.0, "plaza"),
        make_camera((-17.0, 1.7, 18.5), (15.0, 1.4, 18.5), 60.0, "arcade"),
        make_camera((6.0, 3.5, -12.0), (6.0, 0.0, -5.0), 60.0, "clutter"),
        make_camera((8.0, 1.6, 8.0), (0.0, 1.0, 0.0), 50.0, "fountain"),
    )
    # Sun from the south-south-west, 42° high: the north arcade's floor is partly sunlit, the east
    # arcade is in shade, and every object casts a shadow a metre or so long.
    sun = sun_from_irradiance(sun_direction(azimuth_deg=250.0, elevation_deg=42.0))
    return a.build("courtyard", materials, views=views, sun=sun, sky_radiance=DAYLIGHT_SKY_RADIANCE)
