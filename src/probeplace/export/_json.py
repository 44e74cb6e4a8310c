"""JSON export: the documented, versioned probe exchange file ``probeplace.ProbeExport/1``.

Layout (schema: ``schemas/probe-export-1.schema.json``; docs/export.md)::

    {"format": "probeplace.ProbeExport/1",
     "generator": "probeplace",
     "method": "skeleton-sdf", "config": {...}, "units_m": 1.0, "up_axis": "+Y", "handedness": "right",
     "count": 3,
     "positions": [[x, y, z], ...],            # scene units, world frame
     "active": [true, false, true],            # validity: rows a placer switched off
     "inside": [false, false, true],           # optional: probe inside geometry at bake time
     "sh": {"convention": "...", "order": ["Y00", ...], "coefficients": [[[r, g, b] × 9] × count]}}

Numbers are written so that float32 values parse back bit for bit (``_io_util.f32_list``).
"""

from __future__ import annotations

import json
import os
from importlib import resources
from pathlib import Path

import numpy as np

from .._core.files._io import write_json_atomic
from ._data import ExportError, ExportProbes
from ._io_util import f32_list
from ._sh import SH_CONVENTION, SH_ORDER

JSON_FORMAT = "probeplace.ProbeExport/1"
SCHEMA_NAME = "probe-export-1.schema.json"


def schema() -> dict:
    """The JSON Schema (draft 2020-12) of the export file, shipped as package data."""
    return json.loads(resources.files(__package__).joinpath("schemas", SCHEMA_NAME).read_text())


def to_json_doc(probes: ExportProbes) -> dict:
    doc: dict = {
        "format": JSON_FORMAT,
        "generator": "probeplace",
        "method": probes.method,
        "config": probes.metadata,
        "units_m": probes.units_m,
        "up_axis": "+Y",
        "handedness": "right",
        "count": probes.n,
        "positions": f32_list(probes.positions),
        "active": probes.active.tolist(),
    }
    if probes.inside is not None:
        doc["inside"] = probes.inside.tolist()
    if probes.sh is not None:
        coeffs = f32_list(probes.sh)
        doc["sh"] = {"convention": SH_CONVENTION, "order": list(SH_ORDER), "coefficients": coeffs}
    return doc


def write_json(probes: ExportProbes, out: str | os.PathLike) -> list[Path]:
    """Write ``probes`` as a ``probeplace.ProbeExport/1`` JSON file; returns the files written."""
    return [write_json_atomic(out, to_json_doc(probes))]


def from_json_doc(doc: object, where: str = "JSON") -> ExportProbes:
    """Parse a ``probeplace.ProbeExport/1`` document (checks the fields the schema requires)."""
    if not isinstance(doc, dict) or doc.get("format") != JSON_FORMAT:
        raise ExportError(f"{where}: not a probe export file (format {JSON_FORMAT!r} expected)")
    if doc.get("up_axis") != "+Y" or doc.get("handedness") != "right":
        raise ExportError(f"{where}: up_axis must be '+Y' and handedness 'right'")
    try:
        pos = np.asarray(doc["positions"], np.float64).reshape(-1, 3)
        active = np.asarray(doc["active"], bool).reshape(-1)
        count = int(doc["count"])
        sh = None
        if "sh" in doc:
            if list(doc["sh"].get("order", [])) != list(SH_ORDER):
                raise ExportError(f"{where}: unsupported SH coefficient order {doc['sh'].get('order')}")
            sh = np.asarray(doc["sh"]["coefficients"], np.float64).reshape(-1, 9, 3)
        inside = np.asarray(doc["inside"], bool) if "inside" in doc else None
    except (KeyError, ValueError, TypeError, AttributeError) as e:
        raise ExportError(f"{where}: bad probe arrays ({e})") from None
    if count != len(pos):
        raise ExportError(f"{where}: count says {count} probes, positions hold {len(pos)}")
    return ExportProbes(
        positions=pos,
        active=active,
        method=str(doc.get("method", "manual")),
        units_m=float(doc.get("units_m", 1.0)),
        metadata=dict(doc.get("config") or {}),
        sh=sh,
        inside=inside,
    )


def read_json(path: str | os.PathLike) -> ExportProbes:
    """Load a ``probeplace.ProbeExport/1`` file (lossless inverse of :func:`write_json`)."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ExportError(f"{path}: cannot read JSON ({e})") from None
    return from_json_doc(doc, str(path))
