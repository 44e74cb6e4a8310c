"""Checked reading of plain config values (YAML or one-line CLI) for the scene sidecar.

Every helper takes ``at``, the text that locates the value for the user (``"room.probeplace.yaml:
sun.elevation"``, ``"--sun: el"``), and raises :class:`~probeplace._core.ConfigError` with one line
that starts with it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from ..._core import ConfigError


def show(value: Any, limit: int = 60) -> str:
    """``repr`` cut to one short line (a message must stay one line even for a huge or multi-line value)."""
    text = " ".join(repr(value).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def is_number(x: Any) -> bool:
    # bool is an int subclass, but `fov: true` is a mistake, not 1°
    return isinstance(x, int | float) and not isinstance(x, bool)


def number(
    x: Any, at: str, *, lo: float | None = None, hi: float | None = None, open_lo=False, open_hi=False
):
    """A finite float inside the given bounds (closed unless ``open_lo`` / ``open_hi``)."""
    if not is_number(x) or not math.isfinite(float(x)):
        raise ConfigError(f"{at}: must be a finite number, got {show(x)}")
    v = float(x)
    low_bad = lo is not None and (v <= lo if open_lo else v < lo)
    high_bad = hi is not None and (v >= hi if open_hi else v > hi)
    if low_bad or high_bad:
        left = "(" if open_lo else "["
        right = ")" if open_hi else "]"
        lo_s = "-inf" if lo is None else f"{lo:g}"
        hi_s = "inf" if hi is None else f"{hi:g}"
        raise ConfigError(f"{at}: must be in {left}{lo_s}, {hi_s}{right}, got {v:g}")
    return v


def vec3(x: Any, at: str) -> tuple[float, float, float]:
    """Three finite numbers ``[x, y, z]``."""
    if (
        not isinstance(x, list | tuple)
        or len(x) != 3
        or not all(is_number(c) and math.isfinite(float(c)) for c in x)
    ):
        raise ConfigError(f"{at}: must be 3 finite numbers [x, y, z], got {show(x)}")
    return (float(x[0]), float(x[1]), float(x[2]))


def direction3(x: Any, at: str) -> tuple[float, float, float]:
    """A non-zero vector (not normalised: the caller normalises where it matters)."""
    v = vec3(x, at)
    if math.hypot(*v) == 0.0:
        raise ConfigError(f"{at}: must be a non-zero vector, got {show(list(v))}")
    return v


def rgb(x: Any, at: str) -> tuple[float, float, float]:
    """Non-negative linear RGB: three numbers, or one number for grey."""
    if is_number(x):
        x = [x, x, x]
    if (
        not isinstance(x, list | tuple)
        or len(x) != 3
        or not all(is_number(c) and math.isfinite(float(c)) and float(c) >= 0 for c in x)
    ):
        raise ConfigError(
            f"{at}: must be one number or 3 non-negative finite numbers [r, g, b], got {show(x)}"
        )
    return (float(x[0]), float(x[1]), float(x[2]))


def boolean(x: Any, at: str) -> bool:
    if not isinstance(x, bool):
        raise ConfigError(f"{at}: must be true or false, got {show(x)}")
    return x


def name(x: Any, at: str) -> str:
    if not isinstance(x, str) or not x.strip():
        raise ConfigError(f"{at}: must be a non-empty name, got {show(x)}")
    return x


def mapping(x: Any, at: str) -> Mapping:
    if not isinstance(x, Mapping):
        raise ConfigError(f"{at}: must be a mapping of keys to values, got {show(x)}")
    return x


def keyed(d: Mapping, spellings: Mapping[str, str], prefix: str) -> dict[str, tuple[str, Any]]:
    """Canonical key → (where, value), refusing unknown keys and two spellings of one key.

    Args:
        d: the user's mapping.
        spellings: accepted key → canonical key (aliases such as ``az`` → ``azimuth`` included).
        prefix: what locates ``d``, ending in ``": "`` or ``"."``; the message names the key as typed.
    """
    out: dict[str, tuple[str, Any]] = {}
    typed: dict[str, str] = {}
    for k, v in d.items():
        if not isinstance(k, str) or k not in spellings:
            known = ", ".join(sorted(set(spellings)))
            raise ConfigError(f"{prefix}{k}: unknown key; known keys: {known}")
        c = spellings[k]
        if c in out:
            raise ConfigError(f"{prefix}{k}: {c} is given twice (as {typed[c]!r} and {k!r})")
        out[c], typed[c] = (f"{prefix}{k}", v), k
    return out
