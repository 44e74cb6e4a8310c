"""The measured Cornell box, built in code (no file needed).

Geometry: the Cornell University Program of Computer Graphics "Cornell Box data" page
(graphics.cornell.edu/online/box/data.html), millimetres, +Y up, open toward −Z. Reflectances are the
RGB values commonly used for the measured spectra (McGuire's public-domain CornellBox-Original.mtl);
the light's radiance (17, 12, 4) is from the same file. The light quad sits 0.8 mm below the ceiling,
as in the widely used Embree/tinyobjloader copy of the data.
"""

from __future__ import annotations

import numpy as np

from ..._core import Scene
from .._build import build_scene, make_camera, materials_from_table

# name -> list of quads (4 corners each, mm)
_PARTS: dict[str, list[list[tuple[float, float, float]]]] = {
    "floor": [[(552.8, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 559.2), (549.6, 0.0, 559.2)]],
    "light": [[(343.0, 548.0, 227.0), (343.0, 548.0, 332.0), (213.0, 548.0, 332.0), (213.0, 548.0, 227.0)]],
    "ceiling": [[(556.0, 548.8, 0.0), (556.0, 548.8, 559.2), (0.0, 548.8, 559.2), (0.0, 548.8, 0.0)]],
    "back_wall": [[(549.6, 0.0, 559.2), (0.0, 0.0, 559.2), (0.0, 548.8, 559.2), (556.0, 548.8, 559.2)]],
    "green_wall": [[(0.0, 0.0, 559.2), (0.0, 0.0, 0.0), (0.0, 548.8, 0.0), (0.0, 548.8, 559.2)]],
    "red_wall": [[(552.8, 0.0, 0.0), (549.6, 0.0, 559.2), (556.0, 548.8, 559.2), (556.0, 548.8, 0.0)]],
    "short_block": [
        [(130.0, 165.0, 65.0), (82.0, 165.0, 225.0), (240.0, 165.0, 272.0), (290.0, 165.0, 114.0)],
        [(290.0, 0.0, 114.0), (290.0, 165.0, 114.0), (240.0, 165.0, 272.0), (240.0, 0.0, 272.0)],
        [(130.0, 0.0, 65.0), (130.0, 165.0, 65.0), (290.0, 165.0, 114.0), (290.0, 0.0, 114.0)],
        [(82.0, 0.0, 225.0), (82.0, 165.0, 225.0), (130.0, 165.0, 65.0), (130.0, 0.0, 65.0)],
        [(240.0, 0.0, 272.0), (240.0, 165.0, 272.0), (82.0, 165.0, 225.0), (82.0, 0.0, 225.0)],
        [(130.0, 0.0, 65.0), (290.0, 0.0, 114.0), (240.0, 0.0, 272.0), (82.0, 0.0, 225.0)],
    ],
    "tall_block": [
        [(423.0, 330.0, 247.0), (265.0, 330.0, 296.0), (314.0, 330.0, 456.0), (472.0, 330.0, 406.0)],
        [(423.0, 0.0, 247.0), (423.0, 330.0, 247.0), (472.0, 330.0, 406.0), (472.0, 0.0, 406.0)],
        [(472.0, 0.0, 406.0), (472.0, 330.0, 406.0), (314.0, 330.0, 456.0), (314.0, 0.0, 456.0)],
        [(314.0, 0.0, 456.0), (314.0, 330.0, 456.0), (265.0, 330.0, 296.0), (265.0, 0.0, 296.0)],
        [(265.0, 0.0, 296.0), (265.0, 330.0, 296.0), (423.0, 330.0, 247.0), (423.0, 0.0, 247.0)],
        [(423.0, 0.0, 247.0), (472.0, 0.0, 406.0), (314.0, 0.0, 456.0), (265.0, 0.0, 296.0)],
    ],
}

_MATERIAL_OF_PART = {
    "floor": "white",
    "ceiling": "white",
    "back_wall": "white",
    "short_block": "white",
    "tall_block": "white",
    "green_wall": "green",
    "red_wall": "red",
    "light": "light",
}
_MATERIALS = {  # linear RGB reflectance, emitted radiance
    "white": ((0.725, 0.71, 0.68), (0.0, 0.0, 0.0)),
    "red": ((0.63, 0.065, 0.05), (0.0, 0.0, 0.0)),
    "green": ((0.14, 0.45, 0.091), (0.0, 0.0, 0.0)),
    "light": ((0.78, 0.78, 0.78), (17.0, 12.0, 4.0)),
}
_BOX_CENTRE = np.array([278.0, 274.4, 279.6])


def cornell_box() -> Scene:
    """The measured Cornell box in millimetres; walls face inward, blocks outward, light faces −Y."""
    mat_names = list(_MATERIALS)
    verts: list[np.ndarray] = []
    faces: list[np.ndarray] = []
    tri_mat: list[int] = []
    tri_part: list[int] = []
    for part_id, (part, quads) in enumerate(_PARTS.items()):
        corners = np.asarray(quads, np.float64)  # (q, 4, 3)
        part_centre = corners.reshape(-1, 3).mean(axis=0)
        for quad in corners:
            base = sum(len(v) for v in verts)
            n = np.cross(quad[1] - quad[0], quad[2] - quad[0])
            centre = quad.mean(axis=0)
            if part == "light":
                outward = np.array([0.0, -1.0, 0.0])  # emits downward into the box
            elif part.endswith("block"):
                outward = centre - part_centre
            else:
                outward = _BOX_CENTRE - centre
            order = [0, 1, 2, 3] if np.dot(n, outward) > 0 else [0, 3, 2, 1]
            verts.append(quad[order])
            faces.append(base + np.array([[0, 1, 2], [0, 2, 3]]))
            tri_mat += [mat_names.index(_MATERIAL_OF_PART[part])] * 2
            tri_part += [part_id] * 2
    materials = materials_from_table(_MATERIALS, ("base_color", "emission"))
    views = (
        make_camera((278.0, 273.0, -800.0), (278.0, 273.0, -799.0), 39.3, "front"),
        make_camera((278.0, 500.0, 30.0), (278.0, 80.0, 420.0), 65.0, "interior"),
    )
    return build_scene(
        "cornell_box",
        np.concatenate(verts).astype(np.float32),
        np.concatenate(faces),
        np.asarray(tri_mat),
        materials,
        tri_part=np.asarray(tri_part),
        part_names=tuple(_PARTS),
        views=views,
        unit_m=0.001,
        source="builtin:cornell_box",
    )
