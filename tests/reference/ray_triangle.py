"""Brute-force closest ray–triangle hits (Möller & Trumbore 1997, "Fast, minimum storage ray-triangle
intersection"), float64 NumPy, every ray against every triangle: an oracle for small scenes only."""

from __future__ import annotations

import numpy as np


def closest_hits(
    origins: np.ndarray, directions: np.ndarray, triangles: np.ndarray, chunk: int = 256
) -> tuple[np.ndarray, np.ndarray]:
    """Nearest hit distance (inf on a miss) and triangle index (-1) of each ray; both faces count.

    Args:
        origins, directions: (n, 3) rays; directions need not be unit (t is in units of |direction|).
        triangles: (m, 3, 3) corner positions.
    """
    o = np.asarray(origins, np.float64)
    d = np.asarray(directions, np.float64)
    tri = np.asarray(triangles, np.float64)
    v0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    t_best = np.full(len(o), np.inf)
    i_best = np.full(len(o), -1)
    for s in range(0, len(o), chunk):
        oc, dc = o[s : s + chunk, None, :], d[s : s + chunk, None, :]
        p = np.cross(dc, e2[None])
        det = np.sum(e1[None] * p, axis=-1)
        ok = np.abs(det) > 1e-300
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        tv = oc - v0[None]
        u = np.sum(tv * p, axis=-1) * inv
        q = np.cross(tv, e1[None])
        v = np.sum(dc * q, axis=-1) * inv
        t = np.sum(e2[None] * q, axis=-1) * inv
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        t = np.where(hit, t, np.inf)
        i = np.argmin(t, axis=1)
        t_best[s : s + chunk] = t[np.arange(len(i)), i]
        i_best[s : s + chunk] = np.where(np.isfinite(t_best[s : s + chunk]), i, -1)
    return t_best, i_best
