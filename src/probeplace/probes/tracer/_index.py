"""Probe selection indices for the light-field tracer: which probes a ray at a point should try.

* :class:`GridIndex` — probes on a uniform grid (McGuire et al. 2017 §4.1): the cage of eight probes
  around a point is found by arithmetic; the tracer orders them itself (nearest the ray's line first,
  then (i+3) mod 8).
* :class:`VoxelIndex` — any probe set (Wang et al. 2019 §4.1): a voxel grid over the scene bounds holding
  up to K candidate probes per voxel, ranked. Built in NumPy once, looked up in JAX. The same structure,
  built by :func:`nearest_index`, lists each voxel's nearest probes for the tracer's fallback search.

Wang's influence region: for each of the six faces of a probe's bounding cube, the influence distance is
the *median* of the probe's radial distances over the texels whose direction has that face as major axis.
A voxel is a candidate of a probe if its centre lies in the probe's influence box and the probe can see
it; candidates are ranked by Wang's "projected solid angle-weighted visibility" (Ω̄/d̄)·V. For a voxel of
side h at distance d the solid angle is ≈ h²/d², so the score is V·h²/d³; V is the share of the voxel's
nine test points (centre, corners) the probe sees through its own radial-distance map (a shadow-map test).
Voxels that no influence box covers (Wang's full-coverage guarantee does not hold for every set) fall
back to the visible probes, then to the nearest probes, so every voxel has at least one candidate.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int
from scipy.spatial import cKDTree

from ..._core import ConfigError, LightFieldProbes, next_pow2, oct_encode, strip_border, texel_directions

# The nearest index's smallest padded voxel count an axis (:func:`nearest_index`).
_NEAR_MIN_VOXELS = 8


class GridIndex(eqx.Module):
    """Probes on a uniform axis-aligned grid.

    Attributes:
        origin: world position of grid node (0, 0, 0).
        spacing: node spacing per axis (1 on an axis with a single node).
        probe_of_node: probe row at each node, -1 where the node has no usable probe.
        dims: nodes per axis (static).
    """

    origin: Float[Array, "3"]
    spacing: Float[Array, "3"]
    probe_of_node: Int[Array, "nx ny nz"]
    dims: tuple[int, int, int] = eqx.field(static=True)

    def cage(self, x: Float[Array, "3"]) -> tuple[Int[Array, "8"], Int[Array, ""]]:
        """The eight probes of the grid cell containing ``x`` (clamped into the grid), in McGuire's order
        i ↦ base + (i mod 2, ⌊i/2⌋ mod 2, ⌊i/4⌋ mod 2), and the flat id of the cell."""
        dims = jnp.asarray(self.dims, jnp.int32)
        cell = jnp.floor((x - self.origin) / self.spacing).astype(jnp.int32)
        base = jnp.clip(cell, 0, jnp.maximum(dims - 2, 0))
        i = jnp.arange(8, dtype=jnp.int32)
        off = jnp.stack([i % 2, (i // 2) % 2, (i // 4) % 2], axis=-1)
        node = jnp.minimum(base[None, :] + off, dims[None, :] - 1)
        ids = self.probe_of_node[node[:, 0], node[:, 1], node[:, 2]]
        cell_id = (base[0] * dims[1] + base[1]) * dims[2] + base[2]
        return ids, cell_id


class VoxelIndex(eqx.Module):
    """Up to K ranked candidate probes per voxel of a grid over the scene bounds (Wang 2019 §4.1).

    Attributes:
        origin: world position of the grid's lower corner.
        voxel_size: voxel side per axis.
        candidates: probe rows per voxel, best first, -1 padded; the grid may be padded beyond ``dims``
            (:func:`nearest_index`), and those voxels are never read.
        dims: voxels per axis that hold candidates. An array, not a static field: a set's voxel count
            need not compile its own tracer programs (issue 33's demo compiled one per probe spacing).
    """

    origin: Float[Array, "3"]
    voxel_size: Float[Array, "3"]
    candidates: Int[Array, "nx ny nz k"]
    dims: Int[Array, "3"]

    @property
    def k(self) -> int:
        return int(self.candidates.shape[-1])

    def lookup(self, x: Float[Array, "3"]) -> tuple[Int[Array, " k"], Int[Array, ""]]:
        """Candidates of the voxel containing ``x`` (clamped into the grid) and the voxel's flat id."""
        dims = self.dims
        v = jnp.clip(jnp.floor((x - self.origin) / self.voxel_size).astype(jnp.int32), 0, dims - 1)
        return self.candidates[v[0], v[1], v[2]], (v[0] * dims[1] + v[1]) * dims[2] + v[2]


def usable_probes(lf: LightFieldProbes) -> np.ndarray:
    """Probes the tracer may use: active and not inside geometry."""
    return np.asarray(lf.active) & ~np.asarray(lf.inside)


def grid_index(lf: LightFieldProbes, *, rtol: float = 1e-4) -> GridIndex:
    """Recognise the probes as a full uniform grid and index it.

    Args:
        lf: baked probes; *all* rows (usable or not) must sit on the nodes of one axis-aligned grid,
            one probe per node. Unusable probes (inactive, inside geometry) are indexed as -1.
        rtol: tolerance on coordinates, relative to the grid's extent.

    Raises:
        ConfigError: the positions do not form a full uniform grid (use :func:`voxel_index`).
    """
    pos = np.asarray(lf.pos_world, np.float64)
    n = pos.shape[0]
    ext = float(np.ptp(pos, axis=0).max()) or 1.0
    tol = rtol * ext
    dims, origin, spacing, node = [], [], [], []
    for a in range(3):
        vals = np.sort(pos[:, a])
        uniq = vals[np.r_[True, np.diff(vals) > tol]]
        m = len(uniq)
        step = (uniq[-1] - uniq[0]) / (m - 1) if m > 1 else 1.0
        if m > 1 and np.max(np.abs(uniq - (uniq[0] + step * np.arange(m)))) > tol:
            raise ConfigError(f"probe positions are not uniformly spaced along axis {a}: not a uniform grid")
        dims.append(m)
        origin.append(uniq[0])
        spacing.append(step)
        node.append(np.clip(np.round((pos[:, a] - uniq[0]) / step), 0, m - 1).astype(np.int64))
    if dims[0] * dims[1] * dims[2] != n:
        raise ConfigError(f"{n} probes do not fill a {dims[0]}×{dims[1]}×{dims[2]} grid: not a uniform grid")
    table = -np.ones(dims, np.int32)
    table[node[0], node[1], node[2]] = np.arange(n, dtype=np.int32)
    if (table < 0).any():
        raise ConfigError("two probes share a grid node: not a uniform grid")
    table[~np.broadcast_to(usable_probes(lf), (n,))[table]] = -1
    return GridIndex(
        origin=jnp.asarray(origin, jnp.float32),
        spacing=jnp.asarray(spacing, jnp.float32),
        probe_of_node=jnp.asarray(table),
        dims=(int(dims[0]), int(dims[1]), int(dims[2])),
    )


def _influence_boxes(dist: np.ndarray, dirs: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """(n, 2, 3) influence boxes: per cube face (major axis of the texel direction) the median radial
    distance of the probe's texels (Wang 2019 §4.1)."""
    major = np.argmax(np.abs(dirs), axis=-1)  # (m,)
    sign = np.sign(dirs[np.arange(len(dirs)), major])
    lo, hi = pos.copy(), pos.copy()
    for a in range(3):
        for s, box in ((1.0, hi), (-1.0, lo)):
            sel = (major == a) & (sign == s)
            med = np.median(dist[:, sel], axis=1)
            box[:, a] = pos[:, a] + s * med
    return np.stack([lo, hi], axis=1)


def _visible_share(
    lf_dist: np.ndarray, res: int, pos: np.ndarray, points: np.ndarray, slack: float
) -> np.ndarray:
    """(n_probes, n_points, n_test) → share of test points each probe sees (shadow-map test against the
    probe's own nearest-texel radial distance, with a relative ``slack``)."""
    rel = points[None] - pos[:, None, None, :]  # (n, p, t, 3)
    r = np.linalg.norm(rel, axis=-1)
    uv = np.asarray(oct_encode(jnp.asarray(rel / np.maximum(r, 1e-12)[..., None], jnp.float32)))
    idx = np.clip(np.floor((uv + 1.0) * (res / 2.0)), 0, res - 1).astype(np.int64)
    stored = lf_dist[np.arange(len(pos))[:, None, None], idx[..., 1], idx[..., 0]]
    return (r <= stored * (1.0 + slack)).mean(axis=-1)


def voxel_index(
    lf: LightFieldProbes,
    bounds: Float[Array, "2 3"] | np.ndarray,
    *,
    k: int = 4,
    max_voxels_per_axis: int = 32,
    slack: float = 0.02,
) -> VoxelIndex:
    """Build Wang's voxel index of up to ``k`` candidate probes per voxel (NumPy, once per probe set).

    Args:
        lf: baked probes (their radial-distance maps give the influence boxes and the visibility test).
        bounds: (min, max) corners of the region to index (the scene bounds).
        k: candidates kept per voxel (Wang stores four).
        max_voxels_per_axis: voxels along the longest axis; cubic voxels.
        slack: relative depth slack of the visibility test (a point on a surface counts as visible).

    Returns:
        The :class:`VoxelIndex`.

    Raises:
        ConfigError: no usable probe, or bad ``k`` / resolution.
    """
    if k < 1 or max_voxels_per_axis < 1:
        raise ConfigError(
            f"voxel_index needs k ≥ 1 and max_voxels_per_axis ≥ 1, got {k}, {max_voxels_per_axis}"
        )
    usable = usable_probes(lf)
    if not usable.any():
        raise ConfigError("voxel_index: no usable probe (all inactive or inside geometry)")
    b = np.asarray(bounds, np.float64)
    lo, hi = b[0], b[1]
    ext = np.maximum(hi - lo, 1e-9)
    h = float(ext.max()) / max_voxels_per_axis
    dims = tuple(int(max(1, np.ceil(e / h - 1e-6))) for e in ext)
    pos = np.asarray(lf.pos_world, np.float64)
    res = lf.geometry_res  # the geometry maps' resolution (may differ from radiance's)
    dist = np.asarray(strip_border(lf.distance[..., None]))[..., 0].astype(np.float64)
    dirs = np.asarray(texel_directions(res), np.float64).reshape(-1, 3)
    boxes = _influence_boxes(dist.reshape(len(pos), -1), dirs, pos)

    gi = np.stack(np.meshgrid(*(np.arange(d) for d in dims), indexing="ij"), axis=-1).reshape(-1, 3)
    centres = lo + (gi + 0.5) * h
    corners = np.array([[i % 2, (i // 2) % 2, (i // 4) % 2] for i in range(8)], np.float64) - 0.5
    # Test points pulled 10% inside the voxel so a voxel touching a wall is not judged by the wall itself.
    test = centres[:, None, :] + np.concatenate([np.zeros((1, 3)), 0.9 * corners]) * h  # (v, 9, 3)
    cand = -np.ones((len(centres), k), np.int32)
    use = np.flatnonzero(usable)
    chunk = max(1, 200_000 // (len(use) * 9))
    for s in range(0, len(centres), chunk):
        c = centres[s : s + chunk]
        vis = _visible_share(dist[use], res, pos[use], test[s : s + chunk], slack)  # (u, v)
        d = np.linalg.norm(c[None] - pos[use][:, None], axis=-1)
        score = vis * h * h / np.maximum(d, 1e-3 * h) ** 3  # (Ω̄/d̄)·V with Ω̄ ≈ h²/d² (module docstring)
        inside = np.all((c[None] >= boxes[use][:, None, 0]) & (c[None] <= boxes[use][:, None, 1]), -1)
        # Rank: inside an influence box and visible first, then visible, then by nearness.
        tier = np.where(inside & (vis > 0), 2, np.where(vis > 0, 1, 0))
        key = tier * 1e30 + np.where(tier > 0, score, 1.0 / np.maximum(d, 1e-12))
        order = np.argsort(-key, axis=0)[:k]  # (k, v)
        cand[s : s + chunk, : order.shape[0]] = use[order].T
    return VoxelIndex(
        origin=jnp.asarray(lo, jnp.float32),
        voxel_size=jnp.full((3,), h, jnp.float32),
        candidates=jnp.asarray(cand.reshape(*dims, k)),
        dims=jnp.asarray(dims, jnp.int32),
    )


def nearest_index(
    pos: np.ndarray, usable: np.ndarray, bounds, *, radius: float, k: int = 32, max_voxels_per_axis: int = 64
) -> VoxelIndex:
    """For each voxel of a grid over ``bounds`` (voxel side ≈ radius / 2), the ``k`` usable probes nearest
    its centre among those within ``radius`` + half the voxel's diagonal (so every probe within
    ``radius`` of a point of the voxel is a candidate unless more than ``k`` are), nearest first, -1
    padded. The light-field tracer's fallback search reads it instead of scanning every probe.

    The voxel count follows the probes' spacing (through ``radius``), so the grid is padded to a power of
    two voxels an axis, at least 8 (:data:`_NEAR_MIN_VOXELS`; 64 kB of -1 at ``k`` 32): sets that differ
    only in spacing reuse the tracer's compiled programs. The padding is never read (``VoxelIndex.dims``).

    Raises:
        ConfigError: ``radius`` or ``k`` not positive.
    """
    if not radius > 0 or k < 1:
        raise ConfigError(f"nearest_index needs radius > 0 and k ≥ 1, got {radius}, {k}")
    b = np.asarray(bounds, np.float64)
    lo, ext = b[0], np.maximum(b[1] - b[0], 1e-9)
    h = max(0.5 * radius, float(ext.max()) / max_voxels_per_axis)
    dims = tuple(int(max(1, np.ceil(e / h - 1e-6))) for e in ext)
    gi = np.stack(np.meshgrid(*(np.arange(n) for n in dims), indexing="ij"), axis=-1).reshape(-1, 3)
    centres = lo + (gi + 0.5) * h
    use = np.flatnonzero(np.asarray(usable))
    cand = -np.ones((len(centres), k), np.int32)
    if len(use):
        reach = radius + 0.5 * h * np.sqrt(3.0)
        dist, idx = cKDTree(np.asarray(pos, np.float64)[use]).query(centres, k=min(k, len(use)))
        dist, idx = dist.reshape(len(centres), -1), idx.reshape(len(centres), -1)
        cand[:, : idx.shape[1]] = np.where(dist <= reach, use[np.minimum(idx, len(use) - 1)], -1)
    padded = -np.ones((*(next_pow2(n, lo=_NEAR_MIN_VOXELS) for n in dims), k), np.int32)
    padded[: dims[0], : dims[1], : dims[2]] = cand.reshape(*dims, k)
    return VoxelIndex(
        origin=jnp.asarray(lo, jnp.float32),
        voxel_size=jnp.full((3,), h, jnp.float32),
        candidates=jnp.asarray(padded),
        dims=jnp.asarray(dims, jnp.int32),
    )
