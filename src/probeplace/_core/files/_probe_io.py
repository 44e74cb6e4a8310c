"""The ProbeSet file: what ``probeplace place`` writes and ``probeplace export`` / bake read, as
``ProbeSet`` pytrees. A small, human-readable JSON document (written atomically; its layout and the
checks on reading are ``_probe_files``'). Positions are in the scene's world frame and units (``units_m``
metres per unit); ``metadata`` is free-form: config, seed, timings, coverage.
"""

from __future__ import annotations

import os
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from .._errors import ProbeplaceError
from .._types import ProbeSet
from ._io import write_json_atomic
from ._probe_files import PROBE_SET_FORMAT, parse_probe_set, read_json_doc


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
    doc = parse_probe_set(read_json_doc(path, "probe set file"), path)
    probes = ProbeSet(
        pos_world=jnp.asarray(doc.positions, jnp.float32), active=jnp.asarray(doc.active), method=doc.method
    )
    return probes, doc.doc
