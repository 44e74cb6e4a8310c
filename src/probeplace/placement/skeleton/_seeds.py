"""Candidate probe positions from the scene's skeleton (Wang et al. 2019 §3.1), two ways.

* :func:`skeleton_seeds` — SDF skeletonisation (Wang §3.1, Fig. 2): drop voxels outside the scene box,
  inside solids and near surfaces, keep the rest that lie on the ridge of the distance field (the medial
  part: |∇D| < ``ridge``, where the distance stops growing in one direction), cluster them, and return
  the cluster centroids (snapped to the nearest member so a centroid of a curved cluster stays in free
  space). Clusters are balls of radius ``radius_factor``·D around the deepest unclustered voxel (greedy
  cover), so their number follows the scene's rooms and corridors, not a fixed count.
* :func:`medial_axis_seeds` — ball shrinking (Ma, Bae, Choi & Schmidt 2012, "3D medial axis point
  approximation using nearest neighbors and the normal field", Alg. 1): for each surface point p with
  normal n (into free space) a ball tangent at p, centre p + r·n, shrinks to the ball through p and its
  nearest surface point q: r ← |p − q|² / (2 n·(q − p)), until no point is inside. Density is controlled
  as Wang Fig. 3 does, by pre-clustering the surface points by position (grid cells of ``cell``) and
  orientation (normals snapped to the 26 directions of {−1, 0, 1}³): one ball per cluster, from the
  cluster's mean position and normal. Centres with small balls (corners) or outside the box are dropped
  and close centres merged.

Both work on the host (numpy/scipy): they run once per placement.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import spatial

from ..._core import ConfigError
from ..fitness import PlacementProblem


def _lattice_points(problem: PlacementProblem, idx: np.ndarray) -> np.ndarray:
    h = float(problem.grid.voxel_size)
    return np.asarray(problem.grid.origin, np.float64)[None] + h * idx.astype(np.float64)


def skeleton_seeds(
    problem: PlacementProblem,
    *,
    min_clearance_voxels: float = 3.0,
    min_clearance_share: float = 0.25,
    ridge: float = 0.8,
    radius_factor: float = 1.5,
) -> np.ndarray:
    """SDF-skeleton candidates (module docstring).

    Args:
        problem: the fitness model (its grid is already tightened, :func:`tighten_sdf`).
        min_clearance_voxels: voxels nearer than this to a surface are dropped ...
        min_clearance_share: ... and those nearer than this share of the largest clearance in the box
            (the skeleton's twigs toward edges and corners: a probe there sees little).
        ridge: a voxel is on the skeleton when the central-difference gradient of D is shorter than this.
        radius_factor: cluster radius as a multiple of the cluster seed's clearance D.

    Returns:
        (n, 3) float32 positions, world frame; n depends on the scene.
    """
    if not (ridge > 0 and radius_factor > 0 and min_clearance_voxels > 0):
        raise ConfigError("skeleton_seeds: ridge, radius_factor and min_clearance_voxels must be positive")
    v = np.asarray(problem.grid.values, np.float32)
    h = float(problem.grid.voxel_size)
    g = np.gradient(v, h)
    gnorm = np.sqrt(g[0] ** 2 + g[1] ** 2 + g[2] ** 2)
    lo, hi = np.asarray(problem.lo, np.float64), np.asarray(problem.hi, np.float64)
    o = np.asarray(problem.grid.origin, np.float64)
    i_lo = np.clip(np.ceil((lo - o) / h).astype(int), 0, np.array(v.shape) - 1)
    i_hi = np.clip(np.floor((hi - o) / h).astype(int), 0, np.array(v.shape) - 1)
    box = np.zeros(v.shape, bool)
    box[i_lo[0] : i_hi[0] + 1, i_lo[1] : i_hi[1] + 1, i_lo[2] : i_hi[2] + 1] = True
    d_max = float(v[box].max()) if box.any() else 0.0
    keep = box & (v > max(min_clearance_voxels * h, min_clearance_share * d_max)) & (gnorm < ridge)
    idx = np.argwhere(keep)
    pts = _lattice_points(problem, idx)
    if len(pts) == 0:  # no ridge (a tiny or degenerate scene): fall back to the deepest free voxel
        free = np.argwhere(v > 0)
        p = _lattice_points(problem, free)
        ok = np.all((p >= lo) & (p <= hi), axis=1)
        if not ok.any():
            return np.zeros((0, 3), np.float32)
        best = free[ok][np.argmax(v[tuple(free[ok].T)])]
        return _lattice_points(problem, best[None]).astype(np.float32)
    d = v[tuple(idx.T)].astype(np.float64)
    return _ball_cover(pts, d, radius_factor).astype(np.float32)


def _ball_cover(pts: np.ndarray, d: np.ndarray, radius_factor: float) -> np.ndarray:
    """Greedy clustering: the deepest unassigned point takes every unassigned point within factor·D."""
    tree = spatial.cKDTree(pts)
    free = np.ones(len(pts), bool)
    out = []
    for i in np.argsort(-d):
        if not free[i]:
            continue
        members = np.asarray(tree.query_ball_point(pts[i], radius_factor * d[i]), np.int64)
        members = members[free[members]]
        free[members] = False
        c = pts[members].mean(axis=0)
        out.append(pts[members[np.argmin(np.linalg.norm(pts[members] - c, axis=1))]])
    return np.asarray(out, np.float64).reshape(-1, 3)


def _pre_cluster(pos: np.ndarray, nrm: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Group points by (grid cell, normal snapped to {−1, 0, 1}³); mean position and normal per group."""
    cell_key = np.floor(pos / cell).astype(np.int64)
    dir_key = np.rint(nrm * 1.5).clip(-1, 1).astype(np.int64)  # 26 directions (and the axis-aligned 6)
    key = np.concatenate([cell_key, dir_key], axis=1)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    k = inv.max() + 1
    cnt = np.bincount(inv, minlength=k).astype(np.float64)
    mp = np.stack([np.bincount(inv, pos[:, j], k) for j in range(3)], 1) / cnt[:, None]
    mn = np.stack([np.bincount(inv, nrm[:, j], k) for j in range(3)], 1)
    mn /= np.maximum(np.linalg.norm(mn, axis=1, keepdims=True), 1e-12)
    return mp, mn


def _box_exit(p: np.ndarray, n: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Distance along n from p (inside the box) to the box boundary."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(n > 0, (hi - p) / n, np.where(n < 0, (lo - p) / n, np.inf))
    return np.clip(t.min(axis=1), 0.0, None)


def shrink_balls(
    pos: np.ndarray,
    nrm: np.ndarray,
    surface: np.ndarray,
    r_init: np.ndarray,
    *,
    max_iter: int = 40,
    tol: float = 1e-6,
) -> np.ndarray:
    """Ball-shrinking radii (Ma et al. 2012, Alg. 1), vectorised over points.

    Args:
        pos, nrm: points and unit normals (pointing into the region whose medial axis is wanted).
        surface: all surface points (the nearest-neighbour set).
        r_init: starting radius per point.
        max_iter: iteration cap.
        tol: relative tolerance of "no point strictly inside the ball".

    Returns:
        radius per point; the medial point is pos + radius·nrm.
    """
    tree = spatial.cKDTree(surface)
    r = r_init.astype(np.float64).copy()
    active = np.ones(len(pos), bool)
    for _ in range(max_iter):
        if not active.any():
            break
        ia = np.flatnonzero(active)
        c = pos[ia] + r[ia, None] * nrm[ia]
        dist, j = tree.query(c)
        q = surface[j]
        pq = q - pos[ia]
        denom = 2.0 * np.sum(nrm[ia] * pq, axis=1)
        r_new = np.sum(pq * pq, axis=1) / np.where(denom > 0, denom, np.inf)
        # Converged: q is not inside the ball (or is p itself, or lies behind p's tangent plane).
        done = (dist >= r[ia] * (1.0 - tol)) | (denom <= 0) | (r_new >= r[ia])
        upd = ia[~done]
        r[upd] = r_new[~done]
        active[ia[done]] = False
    return r


def medial_axis_seeds(
    problem: PlacementProblem,
    *,
    cell: float | None = None,
    min_radius_voxels: float = 3.0,
    merge_factor: float = 0.5,
) -> np.ndarray:
    """Ball-shrinking medial-axis candidates with position/orientation pre-clustering (module docstring).

    Args:
        problem: the fitness model (its surface samples are the point set).
        cell: pre-clustering cell size, scene units; default the box diagonal / 8. Larger → fewer seeds.
        min_radius_voxels: balls smaller than this many voxels (corners, crevices) are dropped.
        merge_factor: centres closer than this times the larger radius are merged (the deeper one kept).

    Returns:
        (n, 3) float32 positions in free space inside the box.
    """
    lo, hi = np.asarray(problem.lo, np.float64), np.asarray(problem.hi, np.float64)
    diag = float(np.linalg.norm(hi - lo))
    cell = diag / 8.0 if cell is None else float(cell)
    if not (math.isfinite(cell) and cell > 0):
        raise ConfigError(f"medial_axis_seeds: cell must be positive, got {cell}")
    h = float(problem.grid.voxel_size)
    cov = np.asarray(problem.coverable)
    surface = np.asarray(problem.position, np.float64)
    pos, nrm = _pre_cluster(surface[cov], np.asarray(problem.normal, np.float64)[cov], cell)
    # Start from the pre-cluster mean lifted off the surface by a voxel so the ball's own point is not q.
    r0 = np.minimum(0.5 * diag, _box_exit(np.clip(pos, lo, hi), nrm, lo, hi))
    r = shrink_balls(pos, nrm, surface, np.maximum(r0, h))
    centre = pos + r[:, None] * nrm
    ok = (r >= min_radius_voxels * h) & np.all((centre >= lo) & (centre <= hi), axis=1)
    centre, r = centre[ok], r[ok]
    if len(centre) == 0:
        return np.zeros((0, 3), np.float32)
    # Keep centres in free space by the (tightened) SDF.
    v = np.asarray(problem.grid.values, np.float32)
    ijk = np.clip(
        np.rint((centre - np.asarray(problem.grid.origin)) / h).astype(int), 0, np.array(v.shape) - 1
    )
    free = v[tuple(ijk.T)] > min_radius_voxels * h * 0.5
    centre, r = centre[free], r[free]
    # Merge near-duplicates, deepest first.
    order = np.argsort(-r)
    kept: list[int] = []
    tree = spatial.cKDTree(centre)
    taken = np.zeros(len(centre), bool)
    for i in order:
        if taken[i]:
            continue
        kept.append(i)
        near = tree.query_ball_point(centre[i], merge_factor * r[i])
        taken[near] = True
    return centre[kept].astype(np.float32)
