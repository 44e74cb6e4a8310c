"""``temple``: a procedural stand-in for the Iconic Temple of Wang et al. 2019 (§5, Figs. 7 and 10).

What the paper's scene exercises and this one keeps: a raised platform with a glossy floor (glossy
indirect is the paper's primary metric), two rows of round pillars (each "requires at least three probes
to obtain full visibility coverage", Fig. 7) with a centre corridor between them, an interior stair
flight up to a gallery with an object tucked beneath it (a regular grid puts probes "under the stairs",
§5), and a roof, lit by a sun + sky from the open front. Metres, +Y up; front of the hall toward −Z.

Layout (hall interior): x ∈ [−10, 10], z ∈ [−7, 5.5], floor y = 1, roof underside y = 7.
"""

from __future__ import annotations

from ..._core import Scene
from .._build import make_camera, materials_from_table
from .._primitives import MeshAssembler, box, cylinder
from ..light import DAYLIGHT_SKY_RADIANCE, sun_direction, sun_from_irradiance

_FLOOR_Y = 1.0
_ROOF_Y = 7.0
_PILLAR_X = (-8.5, -5.1, -1.7, 1.7, 5.1, 8.5)
_PILLAR_ROWS_Z = (-5.5, 1.5)
_PILLAR_RADIUS = 0.35
_PILLAR_SEGMENTS = 32  # 11.25° facets: well under the 30° crease angle, so shading is smooth
#: The crate under the stair flight, (min, max) corners in metres (tests and placement studies use it).
TEMPLE_UNDER_STAIRS_BOX = ((4.6, 1.0, 4.0), (5.8, 2.0, 5.2))

# name: (linear base colour, roughness, metallic)
_MATERIALS = {
    "ground": ((0.30, 0.33, 0.25), 0.95, 0.0),
    "marble": ((0.78, 0.75, 0.70), 0.25, 0.0),  # glossy floor: glossy indirect matters (Wang 2019 §5)
    "stone": ((0.62, 0.58, 0.52), 0.8, 0.0),
    "column": ((0.72, 0.70, 0.66), 0.5, 0.0),
    "plaster": ((0.60, 0.26, 0.18), 0.85, 0.0),  # coloured walls give visible colour bleeding
    "roof": ((0.42, 0.38, 0.35), 0.9, 0.0),
    "wood": ((0.45, 0.30, 0.18), 0.55, 0.0),
    "crate": ((0.20, 0.34, 0.55), 0.7, 0.0),
    "gold": ((1.0, 0.78, 0.34), 0.3, 1.0),
}


def _add_structure(a: MeshAssembler) -> None:
    a.add(box((-22.0, -0.3, -16.0), (22.0, 0.0, 16.0)), "ground", "ground")
    a.add(box((-11.0, 0.0, -7.0), (11.0, _FLOOR_Y, 7.0)), "marble", "platform")
    for i, h in enumerate((0.25, 0.5, 0.75)):  # entry steps in front, overlapping the platform by 1 cm
        z0 = -7.0 - 0.4 * (3 - i)
        a.add(box((-4.0, 0.0, z0), (4.0, h, -6.99)), "stone", "entry_steps")
    wall_top = _ROOF_Y + 0.05  # walls reach into the roof slab: no light seam under the roof
    a.add(box((-10.5, _FLOOR_Y - 0.05, 5.5), (10.5, wall_top, 6.2)), "plaster", "back_wall")
    a.add(box((-10.5, _FLOOR_Y - 0.05, -2.0), (-9.8, wall_top, 5.6)), "plaster", "left_wall")
    a.add(box((9.8, _FLOOR_Y - 0.05, 2.0), (10.5, wall_top, 5.6)), "plaster", "right_wall")
    a.add(box((-11.0, _ROOF_Y, -7.0), (11.0, _ROOF_Y + 0.5, 7.0)), "roof", "roof")
    a.add(box((-10.0, _ROOF_Y + 0.5, -6.0), (10.0, _ROOF_Y + 1.1, 6.0)), "roof", "roof")


def _add_pillars(a: MeshAssembler) -> None:
    for z in _PILLAR_ROWS_Z:
        for x in _PILLAR_X:
            a.add(
                box((x - 0.45, _FLOOR_Y - 0.01, z - 0.45), (x + 0.45, _FLOOR_Y + 0.3, z + 0.45)),
                "stone",
                "pillars",
            )
            a.add(
                cylinder(
                    (x, _FLOOR_Y + 0.29, z), _PILLAR_RADIUS, _ROOF_Y - _FLOOR_Y - 0.55, _PILLAR_SEGMENTS
                ),
                "column",
                "pillars",
            )
            a.add(
                box((x - 0.45, _ROOF_Y - 0.3, z - 0.45), (x + 0.45, _ROOF_Y + 0.01, z + 0.45)),
                "stone",
                "pillars",
            )


def _add_stairs(a: MeshAssembler) -> None:
    # An open stair flight along the back wall (+X, 12 treads of 0.3 m rise and 0.5 m run) up to a
    # gallery. Treads are 12 cm slabs with nothing below them, so the space under the flight is open
    # and holds a crate that only a fine enough probe layout sees.
    n, rise, run = 12, 0.3, 0.5
    for i in range(n):
        top = _FLOOR_Y + rise * (i + 1)
        x0 = 1.5 + run * i
        a.add(box((x0, top - 0.12, 3.8), (x0 + run + 0.02, top, 5.51)), "wood", "stairs")
    gallery_top = _FLOOR_Y + rise * n
    a.add(box((7.5, gallery_top - 0.2, 2.5), (9.81, gallery_top, 5.51)), "wood", "gallery")
    a.add(cylinder((7.9, _FLOOR_Y - 0.01, 2.8), 0.15, gallery_top - 0.19 - _FLOOR_Y, 16), "column", "gallery")
    lo, hi = TEMPLE_UNDER_STAIRS_BOX
    a.add(box(lo, hi), "crate", "under_stairs_crate")


def _add_altar(a: MeshAssembler) -> None:
    a.add(box((-2.5, _FLOOR_Y - 0.01, 3.6), (-0.5, _FLOOR_Y + 1.0, 5.0)), "stone", "altar")
    a.add(cylinder((-1.5, _FLOOR_Y + 0.99, 4.3), 0.3, 1.6, 24), "gold", "statue")


def temple() -> Scene:
    """The built-in temple scene (about 2,000 triangles, metres, sun + sky from the open front).

    Views: ``hall`` (diagonally across the hall toward the stairs), ``stairs`` (the crate under the
    flight), ``corridor`` (down the corridor between the pillar rows) and ``front`` (from the entry
    steps). All are inside the scene bounds.
    """
    a = MeshAssembler()
    _add_structure(a)
    _add_pillars(a)
    _add_stairs(a)
    _add_altar(a)
    materials = materials_from_table(_MATERIALS, ("base_color", "roughness", "metallic"))
    views = (
        make_camera((-9.0, 2.7, -3.5), (6.0, 2.0, 3.0), 60.0, "hall"),
        make_camera((3.0, 2.0, 0.2), (5.2, 1.5, 4.6), 60.0, "stairs"),
        make_camera((9.3, 2.2, -1.5), (-9.0, 2.0, -1.5), 55.0, "corridor"),
        make_camera((0.0, 2.5, -12.0), (0.0, 3.0, 0.0), 55.0, "front"),
    )
    # Afternoon sun in front of the hall (toward −Z, a little to −X), 38° high: it reaches under the
    # 6 m-high roof about 7.7 m deep, so the front half of the floor is sunlit, striped by the pillars'
    # shadows, and the back half is lit indirectly.
    sun = sun_from_irradiance(sun_direction(azimuth_deg=-115.0, elevation_deg=38.0))
    return a.build("temple", materials, views=views, sun=sun, sky_radiance=DAYLIGHT_SKY_RADIANCE)
