"""Scenes without light for the sidecar tests: a closed box room with a window hole (OBJ + MTL) and a
hand-written glTF (JSON, embedded buffer) with a camera node and a ``KHR_lights_punctual`` sun."""

from __future__ import annotations

import base64
import json
from pathlib import Path

import numpy as np

from probeplace.scene._primitives import box

#: Interior of the room, metres: x ∈ [0, 4], y ∈ [0, 3] (up), z ∈ [0, 5]; walls 0.1 thick.
ROOM_HI = (4.0, 3.0, 5.0)
#: The window: a hole in the +Z wall, x ∈ [1.5, 2.5], y ∈ [1, 2].
WINDOW = ((1.5, 1.0), (2.5, 2.0))
#: A small grey box on the floor; the emitter tests make its material glow.
LAMP = ((1.8, 0.0, 1.8), (2.2, 0.4, 2.2))
T = 0.1


def room_boxes() -> dict[str, list[tuple[tuple[float, ...], tuple[float, ...]]]]:
    """Closed boxes per material: the shell (floor, ceiling, four walls, the +Z one around the window)."""
    (wx0, wy0), (wx1, wy1) = WINDOW
    X, Y, Z = ROOM_HI
    walls = [
        ((-T, Y, -T), (X + T, Y + T, Z + T)),  # ceiling
        ((-T, 0, -T), (0, Y, Z + T)),  # x- wall
        ((X, 0, -T), (X + T, Y, Z + T)),  # x+ wall
        ((0, 0, -T), (X, Y, 0)),  # z- wall
        ((0, 0, Z), (wx0, Y, Z + T)),  # z+ wall, left of the window
        ((wx1, 0, Z), (X, Y, Z + T)),  # right of it
        ((wx0, 0, Z), (wx1, wy0, Z + T)),  # below it
        ((wx0, wy1, Z), (wx1, Y, Z + T)),  # above it
    ]
    return {"wall": walls, "floor": [((-T, -T, -T), (X + T, 0, Z + T))], "lamp": [LAMP]}


def write_room_obj(folder: Path, stem: str = "room", up_axis: str = "y") -> Path:
    """``<folder>/<stem>.obj`` + ``.mtl``: the room, one OBJ part per material; ``up_axis="z"`` writes it
    Z-up (file (x, y, z) = room (x, −z, y)), as a Z-up modelling tool would."""
    lines = [f"mtllib {stem}.mtl"]
    n = 0
    for mat, boxes in room_boxes().items():
        lines.append(f"usemtl {mat}")
        for lo, hi in boxes:
            v, f = box(np.asarray(lo, float), np.asarray(hi, float))
            if up_axis == "z":
                v = np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1)
            lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in v]
            lines += [f"f {a + n + 1} {b + n + 1} {c + n + 1}" for a, b, c in f]
            n += len(v)
    (folder / f"{stem}.obj").write_text("\n".join(lines) + "\n")
    mtl = {"wall": "0.7 0.7 0.7", "floor": "0.5 0.4 0.3", "lamp": "0.8 0.8 0.8"}
    (folder / f"{stem}.mtl").write_text("".join(f"newmtl {k}\nKd {v}\n" for k, v in mtl.items()))
    return folder / f"{stem}.obj"


def write_gltf(path: Path, *, camera_node: dict, light_nodes: list[dict], lights: list[dict]) -> Path:
    """A ``.gltf`` (JSON, base64 buffer): a 4 × 4 m floor quad (material ``floor``), one perspective
    camera (``yfov`` 0.8 rad) on ``camera_node``, and ``lights`` on ``light_nodes``."""
    v = np.array([[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2]], np.float32)
    f = np.array([[0, 2, 1], [0, 3, 2]], np.uint32)  # counter-clockwise seen from +Y
    blob = v.tobytes() + f.tobytes()
    doc = {
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": lights}},
        "scene": 0,
        "scenes": [{"nodes": list(range(2 + len(light_nodes)))}],
        "nodes": [
            {"name": "floor_node", "mesh": 0},
            {"camera": 0, **camera_node},
            *light_nodes,
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.01, "aspectRatio": 1.5}}],
        "meshes": [
            {"name": "floor", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}
        ],
        "materials": [{"name": "floor", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0]}}],
        "accessors": [
            {
                "bufferView": 0,
                "componentType": 5126,
                "count": 4,
                "type": "VEC3",
                "min": [-2, 0, -2],
                "max": [2, 0, 2],
            },
            {"bufferView": 1, "componentType": 5125, "count": 6, "type": "SCALAR"},
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48, "target": 34962},
            {"buffer": 0, "byteOffset": 48, "byteLength": 24, "target": 34963},
        ],
        "buffers": [
            {
                "byteLength": len(blob),
                "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode(),
            }
        ],
    }
    path.write_text(json.dumps(doc, indent=1))
    return path
