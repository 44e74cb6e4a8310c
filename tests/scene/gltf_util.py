"""A tiny hand-written GLB writer for loader tests (independent of trimesh's exporter, so the loader is
tested against the glTF spec rather than against trimesh's own round trip)."""

from __future__ import annotations

import json
import struct

import numpy as np


def write_glb(path, meshes, nodes, materials, cameras=(), extensions_used=()):
    """Write a GLB.

    Args:
        meshes: per mesh, one primitive (vertices (n, 3), faces (m, 3), material index or None) or a
            list of them.
        nodes: list of glTF node dicts (``mesh``, ``camera``, ``children``, ``translation``, ...).
        materials: list of glTF material dicts.
        cameras: list of glTF camera dicts.
    """
    blob = b""
    accessors, views, gl_meshes = [], [], []
    for mesh in meshes:
        prims = []
        for verts, faces, mat in mesh if isinstance(mesh, list) else [mesh]:
            v = np.ascontiguousarray(verts, np.float32)
            f = np.ascontiguousarray(faces, np.uint32)
            for arr, target, ctype, typ in ((v, 34962, 5126, "VEC3"), (f.reshape(-1), 34963, 5125, "SCALAR")):
                data = arr.tobytes()
                views.append(
                    {"buffer": 0, "byteOffset": len(blob), "byteLength": len(data), "target": target}
                )
                acc = {"bufferView": len(views) - 1, "componentType": ctype, "count": len(arr), "type": typ}
                if typ == "VEC3":
                    acc["min"], acc["max"] = arr.min(0).tolist(), arr.max(0).tolist()
                accessors.append(acc)
                blob += data + b"\0" * (-len(data) % 4)
            prim = {"attributes": {"POSITION": len(accessors) - 2}, "indices": len(accessors) - 1}
            if mat is not None:
                prim["material"] = mat
            prims.append(prim)
        gl_meshes.append({"name": f"mesh{len(gl_meshes)}", "primitives": prims})
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [
            {"nodes": [i for i in range(len(nodes)) if not any(i in n.get("children", []) for n in nodes)]}
        ],
        "nodes": list(nodes),
        "meshes": gl_meshes,
        "materials": list(materials),
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
    }
    if cameras:
        doc["cameras"] = list(cameras)
    if extensions_used:
        doc["extensionsUsed"] = list(extensions_used)
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    total = 12 + 8 + len(js) + 8 + len(blob)
    out = struct.pack("<4sII", b"glTF", 2, total)
    out += struct.pack("<II", len(js), 0x4E4F534A) + js
    out += struct.pack("<II", len(blob), 0x004E4942) + blob
    path.write_bytes(out)
    return path
