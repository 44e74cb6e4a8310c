"""The probe files the pipeline writes, named and read in one place: the ProbeSet JSON (``probeplace
place``, ``_probe_io``) and the baked light-field ``.npz`` (``probes.save_probes``), parsed here; the
per-probe sidecars' names and tags (the coverage detail beside a probe set, the evaluation's error
shares), which their writers and ``probeplace view`` share. NumPy only, so that the NumPy-only ``export``
stage reads them with the same tags and checks as the JAX stages.

ProbeSet document::

    {"format": "probeplace.ProbeSet/1", "method": "...", "units_m": 1.0, "up_axis": "+Y",
     "handedness": "right", "positions": [[x, y, z], ...], "active": [true, ...], "metadata": {...}}
"""

from __future__ import annotations

import json
import math
import os
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._errors import ProbeplaceError

PROBE_SET_FORMAT = "probeplace.ProbeSet/1"
#: Each probe's part in the placement's coverage (``placement.CoverageDetail``), beside its probe set.
COVERAGE_DETAIL_FORMAT = "probeplace.CoverageDetail/1"
#: Each probe's share of the evaluation's error (``evaluate._attribute``), in the evaluation's folder.
PROBE_ERROR_FILE = "probe_error.npz"
PROBE_ERROR_FORMAT = "probeplace.ProbeError/1"
#: The baked maps' layout; version 1 stored float32 normal maps (``probes._io`` packs them on load).
LIGHT_FIELD_FORMAT = "probeplace.LightFieldProbes/2"
LIGHT_FIELD_FORMAT_V1 = "probeplace.LightFieldProbes/1"


@dataclass(frozen=True, eq=False)
class ProbeSetDoc:
    """A ProbeSet document, checked: positions (n, 3) float64 in scene units, active flags (n,), the
    method, metres per unit, and the document without its arrays (``metadata`` and the tags)."""

    positions: np.ndarray
    active: np.ndarray
    method: str
    units_m: float
    doc: dict


def coverage_detail_path(probe_set_file: str | os.PathLike) -> Path:
    """Where a probe set's coverage detail lies: beside the file, ``<stem>.coverage.npz`` (``probes.json``
    → ``probes.coverage.npz``). ``probeplace place`` and the experiment runner write it; ``probeplace
    view`` reads it."""
    return Path(probe_set_file).with_suffix(".coverage.npz")


def read_json_doc(path: str | os.PathLike, what: str = "probe file") -> dict:
    """A JSON file's top-level object (``what`` names the file in "not found").

    Raises:
        ProbeplaceError: missing, unreadable, invalid, not an object.
    """
    path = Path(path)
    if not path.is_file():
        raise ProbeplaceError(f"{what} not found: {path}")
    try:
        doc = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ProbeplaceError(f"{path}: not valid JSON ({e})") from None
    if not isinstance(doc, dict):
        raise ProbeplaceError(f"{path}: a JSON object was expected, got {type(doc).__name__}")
    return doc


def parse_probe_set(doc: dict, source: str | os.PathLike) -> ProbeSetDoc:
    """Check a loaded ProbeSet document (``source`` names it in messages).

    Raises:
        ProbeplaceError: wrong format tag, bad shapes, non-finite values, another frame than +Y-up
            right-handed.
    """
    if doc.get("format") != PROBE_SET_FORMAT:
        raise ProbeplaceError(f"{source}: not a probe set file (format {PROBE_SET_FORMAT!r} expected)")
    try:
        pos = np.asarray(doc["positions"], np.float64).reshape(-1, 3)
        active = np.asarray(doc.get("active", [True] * len(pos)), bool).reshape(-1)
        units = float(doc.get("units_m", 1.0))
    except (KeyError, ValueError, TypeError) as e:
        raise ProbeplaceError(f"{source}: bad positions/active arrays ({e})") from None
    if len(active) != len(pos):
        raise ProbeplaceError(f"{source}: {len(pos)} positions but {len(active)} active flags")
    if not np.isfinite(pos).all() or not math.isfinite(units):
        raise ProbeplaceError(f"{source}: non-finite probe positions or units")
    if doc.get("up_axis", "+Y") != "+Y" or doc.get("handedness", "right") != "right":
        raise ProbeplaceError(f"{source}: only right-handed +Y-up probe sets are supported")
    meta = {k: v for k, v in doc.items() if k not in ("positions", "active")}
    return ProbeSetDoc(pos, active, str(doc.get("method", "manual")), units, meta)


def read_light_field_arrays(
    path: str | os.PathLike, keys: tuple[str, ...] | None = None
) -> dict[str, np.ndarray]:
    """The arrays of a baked ``.npz`` (all, or those of ``keys`` it holds: the geometry maps of a 512²
    bake are gigabytes that a reader of positions and irradiance never needs), plus ``format``.

    Raises:
        ProbeplaceError: missing file, not an npz, not a light-field probe file (by its format tag).
    """
    path = Path(path)
    if not path.is_file():
        raise ProbeplaceError(f"probe file not found: {path}")
    try:
        with np.load(path, allow_pickle=False) as z:
            fmt = str(z["format"]) if "format" in z.files else ""
            if fmt not in (LIGHT_FIELD_FORMAT, LIGHT_FIELD_FORMAT_V1):
                raise ProbeplaceError(
                    f"{path}: not a probeplace light-field probe file (format {LIGHT_FIELD_FORMAT} expected)"
                )
            names = z.files if keys is None else [k for k in keys if k in z.files]
            data = {k: z[k] for k in names}
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as e:
        raise ProbeplaceError(f"{path}: not a readable .npz probe file ({e})") from None
    data["format"] = np.asarray(fmt)
    return data
