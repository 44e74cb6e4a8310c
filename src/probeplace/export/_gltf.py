"""glTF 2.0 (.gltf JSON or .glb binary): probes as nodes, their data in ``extras``.

glTF is right-handed with +Y up, the same frame as probeplace, so positions are copied as they are
(https://registry.khronos.org/glTF/specs/2.0/glTF-2.0.html#coordinate-system-and-units). glTF's unit
is the metre; probe positions stay in *scene units* so they line up with the scene file they were
placed in (which an engine imports verbatim), and the root node carries ``scale = units_m`` only when
``to_metres=True``.

Layout::

    scene 0 → node 0 "probeplace_probes"   extras.probeplace = {format, method, config, units_m,
                                           sh_convention?}
                └─ node 1+i "probe_0000"   translation = position, extras.probeplace = {index, active,
                                           inside?, sh? (9 × RGB)}

Inactive rows are kept (named ``probe_0007_inactive``, ``active: false``) so the file round-trips the
whole set; engines see them as empty nodes. Blender keeps ``extras`` as custom properties, three.js'
GLTFLoader as ``userData``, Godot as node metadata.
"""

from __future__ import annotations

import json
import os
import struct
from pathlib import Path

import numpy as np

from .._core.files._io import write_bytes_atomic, write_json_atomic
from ._data import ExportError, ExportProbes
from ._io_util import f32_list
from ._sh import SH_CONVENTION

GLTF_EXTRAS_FORMAT = "probeplace.glTFProbes/1"
_GLB_MAGIC, _GLB_JSON = 0x46546C67, 0x4E4F534A


def to_gltf_doc(probes: ExportProbes, *, to_metres: bool = False) -> dict:
    children = list(range(1, probes.n + 1))
    root: dict = {"name": "probeplace_probes"}
    if to_metres and probes.units_m != 1.0:
        root["scale"] = [probes.units_m] * 3
    if children:
        root["children"] = children
    root["extras"] = {
        "probeplace": {
            "format": GLTF_EXTRAS_FORMAT,
            "method": probes.method,
            "config": probes.metadata,
            "units_m": probes.units_m,
        }
    }
    if probes.sh is not None:
        root["extras"]["probeplace"]["sh_convention"] = SH_CONVENTION
    nodes = [root]
    pos = f32_list(probes.positions)
    sh = None if probes.sh is None else f32_list(probes.sh)
    for i in range(probes.n):
        extras: dict = {"index": i, "active": bool(probes.active[i])}
        if probes.inside is not None:
            extras["inside"] = bool(probes.inside[i])
        if sh is not None:
            extras["sh"] = sh[i]
        name = f"probe_{i:04d}" + ("" if probes.active[i] else "_inactive")
        nodes.append({"name": name, "translation": pos[i], "extras": {"probeplace": extras}})
    return {
        "asset": {"version": "2.0", "generator": "probeplace export"},
        "scene": 0,
        "scenes": [{"name": "probeplace", "nodes": [0]}],
        "nodes": nodes,
    }


def _glb(doc: dict) -> bytes:
    body = json.dumps(doc, separators=(",", ":"), allow_nan=False).encode("utf-8")
    body += b" " * (-len(body) % 4)  # the JSON chunk is padded with spaces to 4 bytes (spec §4.4.3.1)
    total = 12 + 8 + len(body)
    return struct.pack("<III", _GLB_MAGIC, 2, total) + struct.pack("<II", len(body), _GLB_JSON) + body


def write_gltf(probes: ExportProbes, out: str | os.PathLike, *, to_metres: bool = False) -> list[Path]:
    """Write a ``.gltf`` (JSON) or ``.glb`` (binary, by the extension) file; returns the files written."""
    out = Path(out)
    doc = to_gltf_doc(probes, to_metres=to_metres)
    if out.suffix.lower() == ".glb":
        return [write_bytes_atomic(out, _glb(doc))]
    return [write_json_atomic(out, doc)]


def _load_doc(path: Path) -> dict:
    data = path.read_bytes()
    if data[:4] == b"glTF":
        if len(data) < 20:
            raise ExportError(f"{path}: truncated GLB header")
        _magic, version, total = struct.unpack_from("<III", data, 0)
        clen, ctype = struct.unpack_from("<II", data, 12)
        if version != 2 or ctype != _GLB_JSON or total > len(data) or 20 + clen > len(data):
            raise ExportError(f"{path}: not a glTF 2.0 GLB with a JSON chunk")
        data = data[20 : 20 + clen]
    try:
        doc = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ExportError(f"{path}: not valid glTF JSON ({e})") from None
    if not isinstance(doc, dict):
        raise ExportError(f"{path}: not a glTF document")
    return doc


def read_gltf(path: str | os.PathLike) -> ExportProbes:
    """Load probes from a glTF/GLB written by :func:`write_gltf` (lossless).

    Files from other tools work too when their probe nodes carry ``extras.probeplace.index``; a node's
    world position is its translation (rotation/scale of the probe nodes themselves are ignored; the
    root's scale is undone).
    """
    path = Path(path)
    doc = _load_doc(path)
    nodes = doc.get("nodes", [])
    tag = lambda n: ((n.get("extras") or {}).get("probeplace") or {}).get("format")
    roots = [n for n in nodes if isinstance(n, dict) and tag(n) == GLTF_EXTRAS_FORMAT]
    if len(roots) != 1:
        raise ExportError(f"{path}: no probeplace probe root node (extras.probeplace.format)")
    meta = roots[0]["extras"]["probeplace"]
    rows = []
    try:
        for ci in roots[0].get("children", []):
            node = nodes[ci]
            ex = node["extras"]["probeplace"]
            rows.append((int(ex["index"]), node.get("translation", [0.0, 0.0, 0.0]), ex))
    except (KeyError, IndexError, TypeError, ValueError) as e:
        raise ExportError(f"{path}: malformed probe node ({e})") from None
    rows.sort(key=lambda r: r[0])
    if [r[0] for r in rows] != list(range(len(rows))):
        raise ExportError(f"{path}: probe indices are not 0..{len(rows) - 1}")
    has_sh = rows and all("sh" in r[2] for r in rows)
    has_inside = rows and all("inside" in r[2] for r in rows)
    return ExportProbes(
        positions=np.asarray([r[1] for r in rows], np.float64).reshape(-1, 3),
        active=np.asarray([bool(r[2].get("active", True)) for r in rows], bool),
        method=str(meta.get("method", "manual")),
        units_m=float(meta.get("units_m", 1.0)),
        metadata=dict(meta.get("config") or {}),
        sh=np.asarray([r[2]["sh"] for r in rows], np.float64) if has_sh else None,
        inside=np.asarray([r[2]["inside"] for r in rows], bool) if has_inside else None,
    )
