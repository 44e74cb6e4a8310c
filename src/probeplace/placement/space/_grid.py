"""Minimal uniform probe grid (the baseline the "auto" budget is compared with; the baselines issue
builds on it): n_x × n_y × n_z probes at the cell centres of the scene box, counts proportional to the
box's sides for a given spacing. Probes inside geometry are dropped (in the comparison this favours the
grid)."""

from __future__ import annotations

import math

import numpy as np

from ..._core import ConfigError


def grid_dims(lo: np.ndarray, hi: np.ndarray, spacing: float) -> tuple[int, int, int]:
    """Cells per axis: ⌈side / spacing⌉, at least 1."""
    if not (math.isfinite(spacing) and spacing > 0):
        raise ConfigError(f"grid spacing must be positive, got {spacing}")
    ext = np.asarray(hi, np.float64) - np.asarray(lo, np.float64)
    return tuple(int(max(1, math.ceil(e / spacing - 1e-9))) for e in ext)  # type: ignore[return-value]


def uniform_grid(lo: np.ndarray, hi: np.ndarray, dims: tuple[int, int, int]) -> np.ndarray:
    """Cell-centre positions of a dims grid over [lo, hi], (n, 3) float32, x fastest."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    axes = [lo[a] + (np.arange(dims[a]) + 0.5) * (hi[a] - lo[a]) / dims[a] for a in range(3)]
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    return np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1).astype(np.float32)
