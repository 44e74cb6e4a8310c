"""``rooms``: four rooms behind thin walls, for light-leak tests (McGuire et al. 2017 §1; Luo 2022 §3).

Plan (metres, +Y up, interior height 3 m), interior walls centred on the grid lines x = 4, x = 9, z = 5::

      z=9 +-------+-----------------------+
          |       |            C          |
          |   D   +------door-----+-door--+ z=5
          | dark  |      A        |   B   |
          |       |  lit (panel)  door    |
      z=0 +-------+---------------+-------+
         x=0     x=4             x=9     x=13

* A (lit): an emissive panel under the ceiling, the only light in the scene (no sun, black sky).
* B and C: lit only indirectly, through doorways.
* D (dark): sealed. No doorway, no window; a single thin wall (``ROOMS_WALL_THICKNESS``) separates it
  from A. So direct *and* true indirect light in D are exactly zero, and any radiance a probe method
  reports inside :data:`ROOMS_DARK_ROOM_BOUNDS` is light leaked through the wall.

Every solid overlaps its neighbours (walls reach into the floor and ceiling slabs and into each other),
so no ray can slip through a seam between two boxes into D.
"""

from __future__ import annotations

from ..._core import Scene
from .._build import make_camera, materials_from_table
from .._primitives import BOX_FACE_TRIS, MeshAssembler, box

#: Interior (thin) wall thickness in metres.
ROOMS_WALL_THICKNESS = 0.05
_H = 3.0  # interior height
_OUTER = 0.2  # outer walls, floor and ceiling slabs
_DOOR_W, _DOOR_H = 1.0, 2.1
_T2 = ROOMS_WALL_THICKNESS / 2
#: The dark room's interior (air) as (min corner, max corner), metres.
ROOMS_DARK_ROOM_BOUNDS = ((0.0, 0.0, 0.0), (4.0 - _T2, _H, 9.0))
#: The lit room's interior as (min corner, max corner), metres.
ROOMS_LIT_ROOM_BOUNDS = ((4.0 + _T2, 0.0, 0.0), (9.0 - _T2, _H, 5.0 - _T2))
# Emissive panel (the fixture's bottom face) under A's ceiling.
_PANEL_LO, _PANEL_HI = (5.5, _H - 0.03, 1.5), (7.5, _H + 0.05, 3.5)
_PANEL_RADIANCE = (8.0, 7.6, 6.8)

_MATERIALS = {  # name: (linear base colour, roughness, emission)
    "floor": ((0.55, 0.45, 0.35), 0.35, (0.0, 0.0, 0.0)),
    "wall": ((0.75, 0.74, 0.70), 0.9, (0.0, 0.0, 0.0)),
    "wall_green": ((0.20, 0.50, 0.22), 0.9, (0.0, 0.0, 0.0)),
    "ceiling": ((0.80, 0.80, 0.80), 0.95, (0.0, 0.0, 0.0)),
    "fixture": ((0.30, 0.30, 0.30), 0.6, (0.0, 0.0, 0.0)),
    "panel": ((0.80, 0.80, 0.80), 1.0, _PANEL_RADIANCE),
    "furniture": ((0.50, 0.20, 0.12), 0.6, (0.0, 0.0, 0.0)),
}


def _wall_x(
    a: MeshAssembler, x: float, z0: float, z1: float, door: float | None, part: str, mat="wall"
) -> None:
    """Thin wall in the plane x = const from z0 to z1, with an optional doorway centred at z = door."""
    lo_y, hi_y = -_OUTER / 2, _H + _OUTER / 2  # reach into the floor and ceiling slabs
    if door is None:
        a.add(box((x - _T2, lo_y, z0), (x + _T2, hi_y, z1)), mat, part)
        return
    d0, d1 = door - _DOOR_W / 2, door + _DOOR_W / 2
    a.add(box((x - _T2, lo_y, z0), (x + _T2, hi_y, d0 + 0.01)), mat, part)
    a.add(box((x - _T2, lo_y, d1 - 0.01), (x + _T2, hi_y, z1)), mat, part)
    a.add(box((x - _T2, _DOOR_H, d0), (x + _T2, hi_y, d1)), mat, part)  # lintel


def _wall_z(a: MeshAssembler, z: float, x0: float, x1: float, doors: tuple[float, ...], part: str) -> None:
    """Thin wall in the plane z = const from x0 to x1, with doorways centred at the given x."""
    lo_y, hi_y = -_OUTER / 2, _H + _OUTER / 2
    edges = [x0]
    for d in doors:
        edges += [d - _DOOR_W / 2, d + _DOOR_W / 2]
    edges.append(x1)
    for s0, s1 in zip(edges[0::2], edges[1::2], strict=True):  # solid segments, overlapping 1 cm
        a.add(box((s0 - 0.01, lo_y, z - _T2), (s1 + 0.01, hi_y, z + _T2)), "wall", part)
    for d in doors:
        a.add(box((d - _DOOR_W / 2, _DOOR_H, z - _T2), (d + _DOOR_W / 2, hi_y, z + _T2)), "wall", part)


def rooms() -> Scene:
    """The built-in four-room scene (lit room, two indirectly lit rooms, one sealed dark room).

    Views: ``lit_room`` (in A, facing the thin wall to D), ``doorway`` (from B through the door into A),
    ``back_room`` (along C) and ``dark_room`` (inside D, facing the shared wall; black in a correct
    render). All are inside the scene bounds.
    """
    a = MeshAssembler()
    o = _OUTER
    a.add(box((-o, -o, -o), (13 + o, 0.0, 9 + o)), "floor", "floor")
    a.add(box((-o, _H, -o), (13 + o, _H + o, 9 + o)), "ceiling", "ceiling")
    a.add(box((-o, -o, -o), (0.0, _H + o, 9 + o)), "wall", "outer_walls")
    a.add(box((13.0, -o, -o), (13 + o, _H + o, 9 + o)), "wall", "outer_walls")
    a.add(box((-o, -o, -o), (13 + o, _H + o, 0.0)), "wall", "outer_walls")
    a.add(box((-o, -o, 9.0), (13 + o, _H + o, 9 + o)), "wall", "outer_walls")
    # The thin wall between D and A (and C): one box, no opening, reaching into the outer walls.
    _wall_x(a, 4.0, -o / 2, 9 + o / 2, None, "dark_wall", mat="wall_green")
    _wall_x(a, 9.0, 0.0 - o / 2, 5.0, 2.5, "wall_ab")  # A–B doorway
    _wall_z(a, 5.0, 4.0, 13.0 + o / 2, (6.5, 11.0), "wall_c")  # A–C and B–C doorways
    # Light fixture: a closed slab reaching into the ceiling; only its bottom face (-Y) emits.
    a.add(
        box(_PANEL_LO, _PANEL_HI),
        "fixture",
        "light",
        face_materials=dict.fromkeys(BOX_FACE_TRIS["-y"], "panel"),
    )
    # A little furniture so the rooms are not empty boxes.
    a.add(box((5.0, 0.0 - 0.01, 3.2), (6.4, 0.75, 4.2)), "furniture", "table")
    a.add(box((10.5, 0.0 - 0.01, 6.0), (12.5, 1.2, 6.6)), "furniture", "shelf")
    a.add(box((1.0, 0.0 - 0.01, 2.0), (2.2, 0.9, 3.0)), "furniture", "dark_room_box")
    materials = materials_from_table(_MATERIALS, ("base_color", "roughness", "emission"))
    views = (
        make_camera((8.5, 1.6, 0.6), (4.0, 1.2, 3.5), 65.0, "lit_room"),
        make_camera((12.4, 1.6, 2.5), (6.0, 1.2, 2.5), 60.0, "doorway"),
        make_camera((12.5, 1.6, 8.5), (4.5, 1.0, 6.0), 65.0, "back_room"),
        make_camera((0.5, 1.6, 0.5), (3.9, 1.2, 4.0), 70.0, "dark_room"),
    )
    return a.build("rooms", materials, views=views)
