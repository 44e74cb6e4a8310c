"""Small helpers shared by the format modules: exact float text (atomic writes are ``_core.files._io``'s)."""

from __future__ import annotations

import numpy as np


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
