"""Valid space for probes: a clearance from geometry, relocation out of solids, an optional placement region.

A probe position is *valid* when

1. it lies in the placement box [lo, hi] (the scene box unless the method uses another);
2. it lies in the placement :class:`Region` (where the viewer can be: a union of axis-aligned boxes and/or
   a height band above the floor); no region means the whole box;
3. its signed distance is at least the ``clearance`` (:func:`default_clearance` unless configured), read
   from the SDF grid (:func:`probeplace.geometry.lookup_sdf`);
4. when the scene has views, the viewer can get to it: it lies in the free space connected to a view
   camera (``_reach``; not between Sponza's vaults and roof, nor in a sealed void).

:func:`make_valid` makes a set of positions valid, in this order (each step only touches the probes that
need it, so a valid probe comes back bit-identical):

* **projection**: a probe outside the region (or the box) moves to the nearest point of the region inside
  the box (the closest point of the nearest of its boxes, each clipped to the box and to the height band);
* **relocation**: a probe whose SDF is below the clearance moves to the nearest free point, as DDGI probe
  relocation (Majercik et al. 2019 "Dynamic Diffuse Global Illumination with Ray-Traced Irradiance
  Fields" §5; Majercik 2021 "Scaling Probe-Based Real-Time Dynamic Global Illumination for Production"
  §3.1) and Unity APV's virtual offset push probes out of geometry: Newton steps along the SDF gradient,
  ``p ← p + (target − d(p))·∇d/|∇d|`` with target 1.5 × clearance, and a search along 128 directions at
  growing radii where the gradient is useless (deep inside thick solids), the nearer success winning
  (:func:`relocate_out`). The move stays inside the region box the probe is in (each one it is in is tried);
* **drop**: a probe that cannot reach the clearance inside the region (no free space within reach, e.g.
  deep in a solid that fills the box), or whose position is sealed off from the viewer (condition 4:
  ``unreachable``; it is not moved, since the nearest reachable point may be far — the budget fill puts
  a probe where the set needs one instead) is marked ``dropped`` and keeps its input position; the
  caller disables or removes it (DDGI's probe classification turns such probes off).

Every returned non-dropped position is re-checked on the host against all four conditions (float64
comparisons), so ``lookup_sdf(sdf, res.pos[~res.dropped]) >= clearance`` holds exactly.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..._core import ConfigError, Scene, next_pow2, scene_box
from ...geometry import SDFGrid, lookup_sdf, sdf_value, sdf_value_and_grad
from ._reach import ReachableSpace
from ._region import Region

#: Clearance in SDF voxels (``FitnessConfig.clearance_voxels``'s default, so valid probes are feasible
#: for the fitness, refiners and the automatic budget).
CLEARANCE_VOXELS = 2.0
#: The clearance is at least the box's smallest side over this (the default SDF's extent rule, 128
#: voxels along the longest axis, applied to the smallest): it scales with the scene when the SDF is
#: finer than the default.
CLEARANCE_SIDE_DIVISOR = 128.0
# valid_candidates refuses lattices with more points than this (a spacing far too small for the box).
_MAX_CANDIDATES = 1 << 24


def _inward(lo: np.ndarray, hi: np.ndarray, dtype) -> tuple[np.ndarray, np.ndarray] | None:
    """[lo, hi] rounded inward to ``dtype`` (values of dtype inside the float64 box), or None if empty."""
    lo_d, hi_d = lo.astype(dtype), hi.astype(dtype)
    lo_d = np.where(lo_d.astype(np.float64) < lo, np.nextafter(lo_d, np.asarray(np.inf, dtype)), lo_d)
    hi_d = np.where(hi_d.astype(np.float64) > hi, np.nextafter(hi_d, np.asarray(-np.inf, dtype)), hi_d)
    return (lo_d, hi_d) if np.all(hi_d >= lo_d) else None


# ------------------------------------------------------------------------------------ clearance
def default_clearance(scene: Scene | None, sdf: SDFGrid, *, bounds=None) -> float:
    """The default probe clearance: ``max(2·h, smallest box side / 128)``, scene units.

    * 2·h (h the SDF voxel size) is the scene's feature scale: :func:`probeplace.geometry.default_voxel_size`
      puts two voxels across the thinnest tenth (by area) of the solids (and at least 128 along the
      longest axis), so 2·h is at most that thickness: probes fit wherever the scene's small details
      leave a gap of twice it. Two voxels also clear the SDF's trilinear error (≤ h√3/2 ≈ 0.87·h, docs/
      sdf.md): a probe reading ≥ 2·h is truly ≥ 1.1·h from every surface. It equals the fitness's
      feasibility default (``FitnessConfig.clearance_voxels = 2``), so valid probes are feasible for the
      refiners and the automatic budget.
    * the smallest side of the box / 128 (the default SDF's extent rule applied to the smallest side)
      keeps the clearance scaled to the scene when the SDF was built finer than the default; with the
      default SDF it is smaller than 2·h (Cornell box: 2·4.37 = 8.74 mm vs 555/128 = 4.3 mm).

    Args:
        scene: the scene (its box); may be ``None`` with ``bounds``.
        sdf: its SDF grid.
        bounds: an explicit (lo, hi) box instead of the scene's.

    Returns:
        The clearance, positive, at least one voxel.
    """
    lo, hi = scene_box(scene, bounds)
    h = float(sdf.voxel_size)
    return max(CLEARANCE_VOXELS * h, float(np.min(hi - lo)) / CLEARANCE_SIDE_DIVISOR)


# ------------------------------------------------------------------------------------ relocation
def fibonacci_directions(n: int) -> np.ndarray:
    """``n`` unit directions spread evenly over the sphere (a Fibonacci lattice), float32 (n, 3)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (1.0 + 5**0.5) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1).astype(np.float32)


def relocate_out(
    sdf: SDFGrid, pos: np.ndarray, clearance: float, max_steps: int, lo: np.ndarray, hi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Move points to the nearest point with ``d > clearance`` inside [lo, hi]; (positions, reached).

    Two candidates, the closer valid one wins:

    * gradient steps by the missing distance, ``p ← p + (target − d)·∇d/|∇d|`` (DDGI-style): in the
      SDF's exact band (|∇d| ≈ 1) one step lands at the nearest free point;
    * a search along 128 Fibonacci directions at radii growing by half a voxel (the first radius at which
      some direction is free and inside the box, the freest direction there): deep inside thick solids
      the SDF is a flat lower bound (docs/sdf.md) whose gradient is zero or does not point at the
      nearest surface.

    ``target`` = 1.5 × clearance, so a landing point has margin against interpolation error.
    """
    target = jnp.float32(1.5 * clearance)
    h = jnp.float32(0.5) * sdf.voxel_size.astype(jnp.float32)
    n_radii = max(1, int(np.ceil(float(np.linalg.norm(hi - lo)) / float(h))))
    p, ok = _relocate_points(
        sdf,
        jnp.asarray(pos, jnp.float32),
        target,
        jnp.float32(clearance),
        h,
        jnp.asarray(fibonacci_directions(128)),
        jnp.asarray(lo, jnp.float32),
        jnp.asarray(hi, jnp.float32),
        jnp.int32(n_radii),
        max_steps,
    )
    return np.asarray(p, np.float32), np.asarray(ok)


# Module level, values as arguments (only ``max_steps`` static): a new scene, clearance or grid reuses the
# compilation of an equal probe count instead of retracing a closure per call.
@eqx.filter_jit
def _relocate_points(sdf, pos, target, clearance, h, dirs, lo_c, hi_c, n_radii, max_steps: int):
    value = jax.vmap(lambda q: sdf_value(sdf, q))

    def in_box(q):
        return jnp.all((q >= lo_c[None, :]) & (q <= hi_c[None, :]), axis=-1)

    def search(p):
        def cond(state):
            k, found, _ = state
            return (~found) & (k <= n_radii)

        def body(state):
            k, _, _ = state
            cand = p[None, :] + (k.astype(jnp.float32) * h) * dirs
            v = jnp.where(in_box(cand), value(cand), -jnp.inf)
            best = jnp.argmax(v)
            return k + 1, v[best] > target, cand[best]

        _, found, q = jax.lax.while_loop(cond, body, (jnp.int32(1), jnp.bool_(False), p))
        return q, found

    def newton(p):
        def body(_, p):
            d, g = sdf_value_and_grad(sdf, p)
            gn = jnp.sqrt(jnp.sum(g * g))
            ok = (d <= clearance) & (gn > 1e-6)
            return jnp.where(ok, p + (target - d) / jnp.where(ok, gn, 1.0) * g, p)

        q = jax.lax.fori_loop(0, max_steps, body, p)
        return q, (sdf_value(sdf, q) > clearance) & in_box(q[None, :])[0]

    def one(p):
        qn, okn = newton(p)
        qs, oks = search(p)
        dn = jnp.where(okn, jnp.sum((qn - p) ** 2), jnp.inf)
        ds = jnp.where(oks, jnp.sum((qs - p) ** 2), jnp.inf)
        return jnp.where(dn <= ds, qn, qs), okn | oks

    return jax.vmap(one)(pos)


# ------------------------------------------------------------------------------------ make_valid
@dataclasses.dataclass(frozen=True, eq=False)
class ValidSpace:
    """Positions made valid by :func:`make_valid` and what happened to each.

    Attributes:
        pos: (n, 3) positions, world frame, the input's dtype; rows not moved (and dropped rows) are the
            input rows, bit for bit.
        projected: (n,) bool, moved into the region/box (not dropped).
        relocated: (n,) bool, moved out of geometry to the clearance (not dropped).
        moved: (n,) bool, ``projected | relocated``.
        dropped: (n,) bool, no valid position found (position left as given); disable or remove these.
        unreachable: (n,) bool, dropped because its position (valid otherwise) is sealed off from the
            viewer (``_reach``); a subset of ``dropped``.
        clearance: the clearance used, scene units.
        region: the region used.
    """

    pos: np.ndarray
    projected: np.ndarray
    relocated: np.ndarray
    moved: np.ndarray
    dropped: np.ndarray
    unreachable: np.ndarray
    clearance: float
    region: Region

    @property
    def n_moved(self) -> int:
        return int(self.moved.sum())

    @property
    def n_projected(self) -> int:
        return int(self.projected.sum())

    @property
    def n_relocated(self) -> int:
        return int(self.relocated.sum())

    @property
    def n_dropped(self) -> int:
        return int(self.dropped.sum())

    @property
    def valid(self) -> np.ndarray:
        """(n,) bool, ``~dropped``."""
        return ~self.dropped

    def record(self) -> dict:
        """JSON-able summary for run metadata."""
        return {
            "clearance": float(self.clearance),
            "n_relocated": self.n_relocated,
            "n_projected": self.n_projected,
            "n_moved": self.n_moved,
            "n_dropped": self.n_dropped,
            "n_unreachable": int(self.unreachable.sum()),
            "region": self.region.to_config(),
        }


def _check_box(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    if lo.shape != (3,) or hi.shape != (3,) or not np.all(hi > lo):
        raise ConfigError(f"the placement box needs two 3-vectors with hi > lo, got {lo} and {hi}")
    return lo, hi


def _check_clearance(clearance) -> float:
    c = float(clearance)
    if not (math.isfinite(c) and c > 0):
        raise ConfigError(f"clearance must be a positive finite number (scene units), got {clearance}")
    return c


def _inside(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return np.all((p >= lo) & (p <= hi), axis=-1)


def _project(p: np.ndarray, pieces, dtype) -> np.ndarray:
    """Each row moved to the nearest point of the nearest region piece (bounds rounded inward to ``dtype``,
    so the cast result stays inside; rounding is monotone); rows no piece can take come back unchanged."""
    p64 = p.astype(np.float64)
    best = np.full(len(p64), np.inf)
    q_best = p64.copy()
    for plo, phi in pieces:
        box = _inward(plo, phi, dtype)
        if box is None:
            continue
        q = np.clip(p64, box[0].astype(np.float64), box[1].astype(np.float64))
        d2 = np.sum((q - p64) ** 2, axis=1)
        closer = d2 < best
        best[closer], q_best[closer] = d2[closer], q[closer]
    return q_best.astype(dtype)


def make_valid(
    sdf: SDFGrid,
    pos: np.ndarray | jax.Array,
    *,
    clearance: float | int,
    region: Region | Mapping | None = None,
    lo: np.ndarray | jax.Array | Sequence,
    hi: np.ndarray | jax.Array | Sequence,
    max_steps: int = 16,
    reach: ReachableSpace | None = None,
) -> ValidSpace:
    """Project probes into the region, relocate those too close to geometry, drop the rest (module docstring).

    A probe outside the region or the box moves to the nearest point of the region inside the box; then a
    probe whose SDF is below ``clearance`` is relocated (Newton steps along the SDF gradient to 1.5 ×
    clearance, or the nearest free point of a directional search) without leaving the region box it is
    in; one that cannot get there is dropped (``dropped``; its row keeps the input position). Probes
    already valid are not touched. Host code, not differentiable; one jitted relocation call per region
    box, with rows padded to a power of two so varying counts share compilations.

    Args:
        sdf: the scene's SDF grid.
        pos: (n, 3) probe positions, world frame, scene units; any float dtype (kept).
        clearance: the minimum SDF value of a valid probe, scene units (:func:`default_clearance`).
        region: a :class:`Region`, its config mapping, or ``None`` (everywhere in the box).
        lo, hi: the placement box (usually the scene box); the height band's floor defaults to ``lo[1]``.
        max_steps: relocation Newton steps (static: a new value compiles again).
        reach: the reachable free space (``_reach.reachable_space``); a probe outside it is dropped
            (``unreachable``), since no view reads the light it holds. ``None``: no such condition.

    Returns:
        The positions and masks (:class:`ValidSpace`).

    Raises:
        ConfigError: bad clearance, box or region, or a region that does not overlap the box.
        ValueError: ``pos`` is not (n, 3) floats or holds NaN/inf.
    """
    p_in = np.array(pos)  # a copy: the result never aliases the caller's array
    if p_in.ndim != 2 or p_in.shape[1] != 3 or not np.issubdtype(p_in.dtype, np.floating):
        raise ValueError(f"pos must be an (n, 3) float array, got shape {p_in.shape} dtype {p_in.dtype}")
    if not np.all(np.isfinite(p_in)):
        raise ValueError("pos holds NaN or inf")
    c = _check_clearance(clearance)
    lo, hi = _check_box(lo, hi)
    region = Region.from_config(region)
    floor = region.floor if region.floor is not None else float(lo[1])
    pieces = region.pieces(lo, hi, floor=floor)
    if not pieces:
        raise ConfigError(f"region {region.to_config()} does not overlap the placement box [{lo}, {hi}]")
    dtype = p_in.dtype
    n = len(p_in)
    out = p_in.copy()

    def valid_place(q: np.ndarray) -> np.ndarray:
        return _inside(q.astype(np.float64), lo, hi) & region.contains(q, floor=floor)

    # 1. projection: the nearest point of the nearest piece; rows no piece could take stay put and are
    # dropped below
    projected = ~valid_place(p_in)
    if projected.any():
        out[projected] = _project(p_in[projected], pieces, dtype)
    # 2. relocation of the probes below the clearance, inside each piece they are in
    need = lookup_sdf(sdf, out).astype(np.float64) < c
    relocated = np.zeros(n, bool)
    if need.any():
        idx = np.flatnonzero(need)
        start = out[idx]
        start64 = start.astype(np.float64)
        best = np.full(len(idx), np.inf)
        q_best = start.copy()
        for plo, phi in pieces:
            box = _inward(plo, phi, np.float32)  # the relocation computes in float32
            if box is None:
                continue
            inb = np.flatnonzero(_inside(start64, plo, phi))
            if len(inb) == 0:
                continue
            m = len(inb)
            padded = np.repeat(start[inb[:1]].astype(np.float32), next_pow2(m, lo=8), axis=0)
            padded[:m] = start[inb]
            q, ok = relocate_out(sdf, padded, c, int(max_steps), *(b.astype(np.float64) for b in box))
            q = q[:m].astype(dtype)
            # the host check of step 3 per piece, so a candidate failing it does not shadow another piece's
            ok = ok[:m] & (lookup_sdf(sdf, q).astype(np.float64) >= c)
            d2 = np.sum((q.astype(np.float64) - start64[inb]) ** 2, axis=1)
            better = ok & (d2 < best[inb])
            best[inb[better]] = d2[better]
            q_best[inb[better]] = q[better]
        reached = np.isfinite(best)
        out[idx[reached]] = q_best[reached]
        relocated[idx[reached]] = True
    # 3. verify every row on the host; failures are dropped and keep their input position
    ok = valid_place(out) & (lookup_sdf(sdf, out).astype(np.float64) >= c)
    unreachable = ok & ~reach.contains(out) if reach is not None else np.zeros(n, bool)
    dropped = ~ok | unreachable
    out[dropped] = p_in[dropped]
    projected &= ~dropped
    relocated &= ~dropped
    return ValidSpace(
        pos=out,
        projected=projected,
        relocated=relocated,
        moved=projected | relocated,
        dropped=dropped,
        unreachable=unreachable,
        clearance=c,
        region=region,
    )


def valid_candidates(
    sdf: SDFGrid,
    lo: np.ndarray | jax.Array | Sequence,
    hi: np.ndarray | jax.Array | Sequence,
    clearance: float | int,
    region: Region | Mapping | None,
    spacing: float | int,
    reach: ReachableSpace | None = None,
) -> np.ndarray:
    """Lattice points in valid space: for filling a budget with extra probes.

    A lattice of the given spacing, centred in the bounding box of the region inside [lo, hi] (the box
    itself without a region; ⌈side/spacing⌉ points per axis, x fastest), keeping the points in the region
    and the box with SDF ≥ clearance. A region box thinner than ``spacing`` may get no point.

    Args:
        sdf: the scene's SDF grid.
        lo, hi: the placement box; the height band's floor defaults to ``lo[1]``.
        clearance: minimum SDF value, scene units.
        region: a :class:`Region`, its config mapping, or ``None``.
        spacing: lattice spacing, scene units.
        reach: keep only reachable points (``_reach``), or ``None``.

    Returns:
        (m, 3) float32 positions, world frame (m may be 0).

    Raises:
        ConfigError: bad box, clearance, spacing or region, or more than 2²⁴ lattice points.
    """
    c = _check_clearance(clearance)
    lo, hi = _check_box(lo, hi)
    s = float(spacing)
    if not (math.isfinite(s) and s > 0):
        raise ConfigError(f"spacing must be a positive finite number (scene units), got {spacing}")
    region = Region.from_config(region)
    floor = region.floor if region.floor is not None else float(lo[1])
    pieces = region.pieces(lo, hi, floor=floor)
    if not pieces:
        return np.zeros((0, 3), np.float32)
    blo = np.min([a for a, _ in pieces], axis=0)
    bhi = np.max([b for _, b in pieces], axis=0)
    dims = [max(1, math.ceil(e / s - 1e-9)) for e in bhi - blo]
    if math.prod(dims) > _MAX_CANDIDATES:
        raise ConfigError(
            f"spacing {s} makes a {dims} lattice (> {_MAX_CANDIDATES} points); use a larger one"
        )
    centre = 0.5 * (blo + bhi)
    axes = [centre[a] + (np.arange(dims[a]) - 0.5 * (dims[a] - 1)) * s for a in range(3)]
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1).astype(np.float32)
    keep = _inside(pts.astype(np.float64), lo, hi) & region.contains(pts, floor=floor)
    pts = pts[keep]
    if len(pts):
        pts = pts[lookup_sdf(sdf, pts).astype(np.float64) >= c]
    if reach is not None and len(pts):
        pts = pts[reach.contains(pts)]
    return pts
