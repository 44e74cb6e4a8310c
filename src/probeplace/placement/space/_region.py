"""The placement region: where the viewer can be, so where probes may go (issue 18, "valid space").

A :class:`Region` is a union of axis-aligned boxes and/or a height band above the floor, read from a
config (``{"boxes": [[lo, hi], ...], "height": [a, b], "floor": y}``). ``_valid.make_valid`` projects
probes into it; ``Region.pieces`` clips it to a placement box.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping, Sequence
from typing import Any

import jax
import numpy as np

from ..._core import ConfigError

#: Keys of a region config (``Region.from_config``).
REGION_KEYS = ("boxes", "height", "floor")
Box = tuple[tuple[float, float, float], tuple[float, float, float]]


# ------------------------------------------------------------------------------------ region
def _vec3(value: Any, where: str) -> tuple[float, float, float]:
    try:
        a = np.asarray(value, np.float64)
    except (TypeError, ValueError):
        a = None
    if a is None or a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ConfigError(f"{where} must be 3 finite numbers [x, y, z], got {value!r}")
    return (float(a[0]), float(a[1]), float(a[2]))


def _is_list(value: Any) -> bool:
    return isinstance(value, Sequence) and not isinstance(value, (str, bytes))


def _parse_boxes(value: Any) -> tuple[Box, ...]:
    if value is None:
        return ()
    if not _is_list(value):
        raise ConfigError(f"region.boxes must be a list of [[x, y, z], [x, y, z]], got {value!r}")
    boxes = []
    for i, b in enumerate(value):
        if not _is_list(b) or len(b) != 2:
            raise ConfigError(f"region.boxes[{i}] must be [[x, y, z], [x, y, z]] (lo, hi), got {b!r}")
        lo, hi = _vec3(b[0], f"region.boxes[{i}][0]"), _vec3(b[1], f"region.boxes[{i}][1]")
        if not all(a < c for a, c in zip(lo, hi, strict=True)):
            raise ConfigError(f"region.boxes[{i}] needs lo < hi on every axis, got lo={lo}, hi={hi}")
        boxes.append((lo, hi))
    return tuple(boxes)


def _parse_height(value: Any) -> tuple[float, float] | None:
    if value is None:
        return None
    try:
        h = np.asarray(value, np.float64)
    except (TypeError, ValueError):
        h = None
    if h is None or h.shape != (2,) or not np.all(np.isfinite(h)) or not h[0] < h[1]:
        raise ConfigError(
            f"region.height must be [min_height, max_height], finite with min < max, got {value!r}"
        )
    return (float(h[0]), float(h[1]))


def _parse_floor(value: Any) -> float | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise ConfigError(f"region.floor must be a finite number (the floor's y), got {value!r}")
    return float(value)


@dataclasses.dataclass(frozen=True)
class Region:
    """Where probes may go (besides the placement box): a union of boxes, intersected with a height band.

    Attributes:
        boxes: axis-aligned boxes ``((x0, y0, z0), (x1, y1, z1))``, world frame, scene units, lo < hi per
            axis; a probe may be in any of them. Empty: no box constraint. Stored as float tuples.
        height: ``(min_height, max_height)``, min < max, scene units above the floor along +Y: a probe
            needs ``floor + min_height ≤ y ≤ floor + max_height``. ``None``: no band.
        floor: the floor's y; ``None`` uses the lowest y of the placement box (the scene box's), which
            :func:`make_valid` and :func:`valid_candidates` pass in.

    ``Region()`` (also ``Region.from_config(None)`` or ``{}``) is everywhere.

    Raises:
        ConfigError: a malformed box or one with lo ≥ hi on some axis, a band with min ≥ max, non-finite
            numbers (the message names the field: ``region.boxes[i]``, ``region.height``, ``region.floor``).
    """

    boxes: Sequence = ()
    height: Sequence | None = None
    floor: float | int | None = None

    def __post_init__(self):
        # normalise to hashable float tuples (config lists and ints welcome)
        object.__setattr__(self, "boxes", _parse_boxes(self.boxes))
        object.__setattr__(self, "height", _parse_height(self.height))
        object.__setattr__(self, "floor", _parse_floor(self.floor))

    @classmethod
    def from_config(cls, value: Any) -> Region:
        """Parse a config value: ``None``, a :class:`Region`, or a mapping with optional keys
        ``boxes`` (``[[[x, y, z], [x, y, z]], ...]``), ``height`` (``[min_height, max_height]``) and
        ``floor`` (a number). Missing or null keys mean no constraint.

        Raises:
            ConfigError: not a mapping, an unknown key, or a bad value (the message names the key).
        """
        if value is None:
            return cls()
        if isinstance(value, Region):
            return value
        if not isinstance(value, Mapping):
            raise ConfigError(
                f"region must be null or a mapping with keys {list(REGION_KEYS)}, got {type(value).__name__}"
            )
        unknown = sorted(str(k) for k in value if k not in REGION_KEYS)
        if unknown:
            raise ConfigError(f"region has unknown key(s) {unknown}; expected some of {list(REGION_KEYS)}")
        # parsed here too, so that a wrong type is a ConfigError rather than the constructor's type check
        return cls(
            boxes=_parse_boxes(value.get("boxes")),
            height=_parse_height(value.get("height")),
            floor=_parse_floor(value.get("floor")),
        )

    def to_config(self) -> dict | None:
        """The JSON-able form :meth:`from_config` reads back (``None`` for everywhere)."""
        if self.is_everywhere:
            return None
        return {
            "boxes": [[list(lo), list(hi)] for lo, hi in self.boxes],
            "height": None if self.height is None else list(self.height),
            "floor": self.floor,
        }

    @property
    def is_everywhere(self) -> bool:
        """No box and no height band (``floor`` alone constrains nothing)."""
        return not self.boxes and self.height is None

    def _floor(self, floor: float | int | None) -> float:
        f = self.floor if self.floor is not None else floor
        if f is None:
            raise ValueError("a region with a height band needs a floor: set Region.floor or pass floor=")
        return float(f)

    def contains(self, pos: np.ndarray | jax.Array, *, floor: float | int | None = None) -> np.ndarray:
        """Which points lie in the region (boundaries included); the placement box is not checked.

        Args:
            pos: points (..., 3), world frame; compared in float64.
            floor: the floor's y when :attr:`floor` is ``None`` (needed only with a height band).

        Returns:
            bool (...,).

        Raises:
            ValueError: ``pos`` does not end in 3, or a height band without any floor.
        """
        p = np.asarray(pos, np.float64)
        if p.shape[-1:] != (3,):
            raise ValueError(f"pos must have shape (..., 3), got {p.shape}")
        ok = np.ones(p.shape[:-1], bool)
        if self.boxes:
            in_any = np.zeros(p.shape[:-1], bool)
            for lo, hi in self.boxes:
                in_any |= np.all((p >= np.asarray(lo)) & (p <= np.asarray(hi)), axis=-1)
            ok &= in_any
        if self.height is not None:
            f = self._floor(floor)
            ok &= (p[..., 1] >= f + self.height[0]) & (p[..., 1] <= f + self.height[1])
        return ok

    def pieces(
        self,
        lo: np.ndarray | jax.Array | Sequence,
        hi: np.ndarray | jax.Array | Sequence,
        *,
        floor: float | int | None = None,
    ) -> list[tuple[np.ndarray, np.ndarray]]:
        """The region inside [lo, hi] as boxes (float64 (lo, hi) pairs, non-empty, possibly overlapping):
        each region box (or [lo, hi] itself without boxes) clipped to [lo, hi] and to the height band.
        Boxes that miss [lo, hi] or have zero thickness there are left out."""
        lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
        raw = [(np.asarray(a), np.asarray(b)) for a, b in self.boxes] or [(lo, hi)]
        out = []
        for a, b in raw:
            plo, phi = np.maximum(a, lo), np.minimum(b, hi)
            if self.height is not None:
                f = self._floor(floor)
                plo[1], phi[1] = max(plo[1], f + self.height[0]), min(phi[1], f + self.height[1])
            if np.all(phi > plo):
                out.append((plo, phi))
        return out
