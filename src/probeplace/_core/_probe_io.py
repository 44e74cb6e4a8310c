"""The ProbeSet file: what ``probeplace place`` writes and ``probeplace export`` / bake read.

A small, human-readable JSON document (written atomically)::

    {"format": "probeplace.ProbeSet/1", "method": "...", "units_m": 1.0, "up_axis": "+Y",
     "handedness": "right", "positions": [[x, y, z], ...], "active": [true, ...],
     "metadata": {...free-form: config, seed, timings, coverage...}}

Positions are in the scene's world frame and units (``units_m`` metres per unit).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from ._errors import ProbeplaceError
from ._io import write_json_atomic
from ._types import ProbeSet

PROBE_SET_FORMAT = "probeplace.ProbeSet/1"


def save_probe_set(
    path: str | os.PathLike, probes: ProbeSet, *, units_m: float = 1.0, metadata: dict | None = None
) -> Path:
    """Write a ProbeSet file (see the module docstring). ``metadata`` must be JSON-serialisable."""
    pos = np.asarray(probes.pos_world, np.float64)
    if not np.isfinite(pos).all():
        raise ProbeplaceError("cannot save a probe set with NaN or infinite positions")
    doc = {
        "format": PROBE_SET_FORMAT,
        "method": probes.method,
        "units_m": float(units_m),
        "up_axis": "+Y",
        "handedness": "right",
        "positions": pos.tolist(),
        "active": np.asarray(probes.active, bool).tolist(),
        "metadata": metadata or {},
    }
    return write_json_atomic(path, doc)


def load_probe_set(path: str | os.PathLike) -> tuple[ProbeSet, dict]:
    """Read a ProbeSet file; returns (probes as float32, the whole document minus the arrays).

    Raises:
        ProbeplaceError: missing file, invalid JSON, wrong format tag, bad shapes or non-finite values.
    """
    path = Path(path)
    if not path.is_file():
        raise ProbeplaceError(f"probe set file not found: {path}")
    try:
        doc = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ProbeplaceError(f"{path}: not valid JSON ({e})") from None
    if not isinstance(doc, dict) or doc.get("format") != PROBE_SET_FORMAT:
        raise ProbeplaceError(f"{path}: not a probe set file (format {PROBE_SET_FORMAT!r} expected)")
    try:
        pos = np.asarray(doc["positions"], np.float64).reshape(-1, 3)
        active = np.asarray(doc.get("active", [True] * len(pos)), bool).reshape(-1)
    except (KeyError, ValueError, TypeError) as e:
        raise ProbeplaceError(f"{path}: bad positions/active arrays ({e})") from None
    if len(active) != len(pos):
        raise ProbeplaceError(f"{path}: {len(pos)} positions but {len(active)} active flags")
    if not np.isfinite(pos).all() or not math.isfinite(float(doc.get("units_m", 1.0))):
        raise ProbeplaceError(f"{path}: non-finite probe positions or units")
    probes = ProbeSet(
        pos_world=jnp.asarray(pos, jnp.float32),
        active=jnp.asarray(active),
        method=str(doc.get("method", "manual")),
    )
    meta = {k: v for k, v in doc.items() if k not in ("positions", "active")}
    return probes, meta
