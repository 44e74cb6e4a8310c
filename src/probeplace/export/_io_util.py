"""Small helpers shared by the format modules: atomic writes, exact float text, JSON sidecars."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file renamed into place (no half-written files)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the file the usual permissions
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    return write_bytes_atomic(path, text.encode("utf-8"))


def dumps_json(doc: Any) -> str:
    """Deterministic JSON text (indent 1, key order as built, trailing newline, no NaN)."""
    return json.dumps(doc, indent=1, allow_nan=False) + "\n"


def f32_list(a: np.ndarray) -> list:
    """float32 array → nested lists of Python floats that parse back to the *same* float32 values.

    A float32 widened to float64 is exact, and ``repr`` of a float64 round-trips, so
    ``np.float32(float(text)) == value`` bit for bit: JSON text loses nothing.
    """
    return np.asarray(a, np.float32).astype(np.float64).tolist()


def fmt_f32(x: float | np.floating) -> str:
    """Shortest text of a float32 that parses back to the same float32 (for YAML/.tscn/USD text)."""
    v = np.float32(x)
    s = np.format_float_positional(v, unique=True, trim="-")  # shortest round-trip repr at float32
    return "0" if s in ("-0", "0") else s
