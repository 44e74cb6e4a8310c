"""Stack-free traversal of a threaded BVH (:mod:`._bvh_build`) in JAX, scheduled as a wavefront.

Each ray walks forward through the item array of its direction octant: a box it enters → next item, a box
it misses → the box's skip link, a triangle → test it, then the next item (Smits 1998; Hachisuka 2015 for
the per-octant orderings). Nothing is pushed or popped, so one step is the same small, branch-free piece
of work for every lane — what a vmapped loop needs.

Two schedules of that walk (both measured in docs/raycast.md):

* ``"fused"`` — every step reads one 64-byte item row and evaluates both the slab test and the
  Möller–Trumbore test, keeping whichever applies. Simple; but ~94 % of the items a Sponza ray visits are
  boxes, so most of the triangle arithmetic is thrown away.
* ``"deferred"`` (default) — box steps read 32-byte box rows only; a lane that reaches a triangle
  *parks* its id in a one-slot buffer and walks on (a second triangle waits until the slot is free).
  Every ``box_steps`` box steps, one triangle step tests the parked triangles of all lanes. Triangle work
  falls from every step to one step in ``box_steps + 1``; the price is that a box test may use a
  closest-hit distance one triangle stale (a few extra box visits, never a wrong answer, since the final
  answer is the minimum over every triangle tested). This is the "postponed leaf" idea of Aila & Laine
  2009 ("Understanding the efficiency of ray traversal on GPUs", §3) without its warp vote.

Wavefront: ``lanes`` rays advance together; every ``rounds`` inner rounds, lanes whose ray finished write
their result and take the next ray of the queue, so a few long rays do not hold a whole batch. Rays are
first sorted by direction octant and the Morton code of their origin (coherent lanes share the top of
the tree in cache, and lanes of one wavefront read the same octant layout).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float, Int

from .._core import take_queued, write_finished

# Slab-test exit distances are scaled up by 1 + 2·γ(3) (Ize 2013, "Robust BVH ray traversal", JCGT 2(2),
# Eq. 5) so that float32 rounding never culls a box the exact ray enters (γ(n) = n·ε / (1 − n·ε)).
_F32_EPS = float(jnp.finfo(jnp.float32).eps) / 2
_ROBUST_SCALE = 1.0 + 2.0 * (3 * _F32_EPS / (1 - 3 * _F32_EPS))


def _bits_int(x):
    return jax.lax.bitcast_convert_type(x, jnp.int32)


def _octant(d):
    neg = (d < 0).astype(jnp.int32)
    return neg[:, 0] | (neg[:, 1] << 1) | (neg[:, 2] << 2)


def _spread_bits(x):
    """Insert two zero bits between each of the low 10 bits of ``x`` (uint32), for a 3D Morton code."""
    x = (x | (x << 16)) & 0x030000FF
    x = (x | (x << 8)) & 0x0300F00F
    x = (x | (x << 4)) & 0x030C30C3
    return (x | (x << 2)) & 0x09249249


def ray_order(origins: Float[Array, "n 3"], directions: Float[Array, "n 3"]) -> Int[Array, " n"]:
    """Permutation sorting rays by (direction octant, Morton code of the origin at 9 bits per axis)."""
    lo = jnp.min(origins, axis=0, keepdims=True)
    ext = jnp.maximum(jnp.max(origins, axis=0, keepdims=True) - lo, jnp.finfo(origins.dtype).tiny)
    q = jnp.clip((origins - lo) / ext * 511.0, 0.0, 511.0).astype(jnp.uint32)
    code = _spread_bits(q[:, 0]) | (_spread_bits(q[:, 1]) << 1) | (_spread_bits(q[:, 2]) << 2)
    key = code | (_octant(directions).astype(jnp.uint32) << 27)
    return jnp.argsort(key).astype(jnp.int32)


def _slab(near, far, o, inv, tb):
    """Entered? for boxes given as (near, far) corners for the ray's octant; t interval [0, tb]."""
    tn = jnp.maximum(
        jnp.maximum((near[0] - o[0]) * inv[0], (near[1] - o[1]) * inv[1]),
        jnp.maximum((near[2] - o[2]) * inv[2], 0.0),
    )
    tf = jnp.minimum(
        jnp.minimum((far[0] - o[0]) * inv[0], (far[1] - o[1]) * inv[1]),
        jnp.minimum((far[2] - o[2]) * inv[2], tb),
    )
    return tn <= tf * _ROBUST_SCALE


def _moller_trumbore(v0, e1, e2, o, d):
    """(t, u, v, inside) for column-wise triangles, Möller & Trumbore 1997 (as in ``intersect_triangles``)."""
    px = d[1] * e2[2] - d[2] * e2[1]
    py = d[2] * e2[0] - d[0] * e2[2]
    pz = d[0] * e2[1] - d[1] * e2[0]
    det = e1[0] * px + e1[1] * py + e1[2] * pz
    inv_det = 1.0 / det  # det = 0 (parallel) gives inf/NaN: every comparison below is then False
    sx, sy, sz = o[0] - v0[0], o[1] - v0[1], o[2] - v0[2]
    u = (sx * px + sy * py + sz * pz) * inv_det
    qx = sy * e1[2] - sz * e1[1]
    qy = sz * e1[0] - sx * e1[2]
    qz = sx * e1[1] - sy * e1[0]
    v = (d[0] * qx + d[1] * qy + d[2] * qz) * inv_det
    t = (e2[0] * qx + e2[1] * qy + e2[2] * qz) * inv_det
    inside = (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    return t, u, v, inside


def _cols(rows, first, n=3, dtype=None):
    return tuple(rows[:, first + k].astype(dtype or rows.dtype) for k in range(n))


def _fused_step(items, st, o, d, iv, *, dtype, sentinel, any_hit):
    """One fused step: one item-row read, slab-tested as a box and Möller–Trumbore-tested as a triangle."""
    idx, tb, tr, bu, bv, pend = st
    row = jax.lax.optimization_barrier(items[idx])  # one row gather, not one per column
    link, tid = _bits_int(row[:, 9]), _bits_int(row[:, 10])
    is_tri = link < 0
    entered = _slab(_cols(row, 0, dtype=dtype), _cols(row, 3, dtype=dtype), o, iv, tb)
    tri_cols = (_cols(row, 0, dtype=dtype), _cols(row, 3, dtype=dtype), _cols(row, 6, dtype=dtype))
    t, u, v, inside = _moller_trumbore(*tri_cols, o, d)
    better = is_tri & inside & (t < tb)
    nxt = jnp.where(is_tri, ~link, jnp.where(entered, idx + 1, link))
    if any_hit:
        nxt = jnp.where(better, sentinel, nxt)
    return (
        nxt,
        jnp.where(better, t, tb),
        jnp.where(better, tid, tr),
        jnp.where(better, u, bu),
        jnp.where(better, v, bv),
        pend,
    )


def _box_step(items, st, o, iv, *, dtype, no_tri):
    """One deferred box step: slab-test a box row, or park a reached triangle in the lane's free slot."""
    idx, tb, tr, bu, bv, pend = st
    row = jax.lax.optimization_barrier(items[idx])
    link, tid = _bits_int(row[:, 6]), _bits_int(row[:, 7])
    is_tri = link < 0
    entered = _slab(_cols(row, 0, dtype=dtype), _cols(row, 3, dtype=dtype), o, iv, tb)
    park = is_tri & (pend == no_tri)
    nxt = jnp.where(is_tri, jnp.where(park, ~link, idx), jnp.where(entered, idx + 1, link))
    return nxt, tb, tr, bu, bv, jnp.where(park, tid, pend)


def _tri_step(triangles, st, o, d, *, sentinel, no_tri, any_hit):
    """One deferred triangle step: test every lane's parked triangle, then empty the slot."""
    idx, tb, tr, bu, bv, pend = st
    row = jax.lax.optimization_barrier(triangles[pend])
    t, u, v, inside = _moller_trumbore(_cols(row, 0), _cols(row, 3), _cols(row, 6), o, d)
    better = inside & (t < tb)
    if any_hit:
        idx = jnp.where(better, sentinel, idx)
    return (
        idx,
        jnp.where(better, t, tb),
        jnp.where(better, pend, tr),
        jnp.where(better, u, bu),
        jnp.where(better, v, bv),
        jnp.full_like(pend, no_tri),
    )


def _refill(carry, *, start, ray_rows, n, sentinel, no_tri):
    """Write finished lanes' hits to the output and hand each free lane the next queued ray (wavefront;
    ``_core.maths._lanes``)."""
    ray, st, nxt, out = carry
    idx, tb, tr, bu, bv, pend = st
    finished = (ray >= 0) & (idx == sentinel) & (pend == no_tri)
    out = write_finished(out, finished, ray, (tb, tr, bu, bv), n)
    free = finished | (ray < 0)
    queued, take, nxt = take_queued(free, nxt, n)
    ray = jnp.where(free, queued, ray)
    safe = jnp.clip(ray, 0, n - 1)
    idx = jnp.where(free, jnp.where(take, start[safe], sentinel), idx)
    tb = jnp.where(free, ray_rows[safe, 9], tb)
    tr = jnp.where(free, -1, tr)
    return ray, (idx, tb, tr, bu, bv, pend), nxt, out


def traverse(
    items: Float[Array, "n_total c"],
    triangles: Float[Array, "n_tri1 16"] | None,
    origins: Float[Array, "n 3"],
    directions: Float[Array, "n 3"],
    t_max: Float[Array, " n"],
    *,
    n_items: int,
    sentinel: int,
    schedule: str,
    any_hit: bool,
    lanes: int,
    rounds: int,
    box_steps: int,
    sort_rays: bool,
):
    """Closest (or any) hit per ray. Returns (t, tri, u, v); t = inf and tri = -1 on a miss.

    ``items`` is :func:`pack_items` (fused) or :func:`pack_boxes` (deferred, with ``triangles`` from
    :func:`pack_triangles`). Static arguments as in :class:`~probeplace.geometry.BVHCaster`.
    """
    dtype = origins.dtype
    n = origins.shape[0]
    # tables stay float32 (links and ids are stored as int32 bits in them); geometry is cast per row
    if triangles is not None:
        triangles = triangles.astype(dtype)
        no_tri = triangles.shape[0] - 1  # NaN row: "slot empty"
    else:
        no_tri = -1
    if sort_rays:
        perm = ray_order(origins, directions)
        origins, directions, t_max = origins[perm], directions[perm], t_max[perm]
    tiny = jnp.asarray(jnp.finfo(dtype).tiny, dtype)
    # 1/d with ±0 mapped to a huge value of the sign _octant assigns (0 and -0 both count as positive)
    inv = 1.0 / jnp.where(directions == 0, tiny, directions)
    start = _octant(directions) * n_items
    ray_rows = jnp.concatenate([origins, directions, inv, t_max[:, None]], axis=1)  # (n, 10)
    w = max(1, min(lanes, n))

    def round_(st, o, d, iv):
        if schedule == "fused":
            for _ in range(box_steps + 1):
                st = _fused_step(items, st, o, d, iv, dtype=dtype, sentinel=sentinel, any_hit=any_hit)
            return st
        for _ in range(box_steps):
            st = _box_step(items, st, o, iv, dtype=dtype, no_tri=no_tri)
        return _tri_step(triangles, st, o, d, sentinel=sentinel, no_tri=no_tri, any_hit=any_hit)

    def refill(carry):
        return _refill(carry, start=start, ray_rows=ray_rows, n=n, sentinel=sentinel, no_tri=no_tri)

    def cond(carry):
        ray, _, nxt, _ = carry
        return (nxt < n) | jnp.any(ray >= 0)

    def body(carry):
        ray, st, nxt, out = carry
        r = jax.lax.optimization_barrier(ray_rows[jnp.clip(ray, 0, n - 1)])
        o, d, iv = _cols(r, 0), _cols(r, 3), _cols(r, 6)
        st = jax.lax.fori_loop(0, rounds, lambda _, s: round_(s, o, d, iv), st)
        return refill((ray, st, nxt, out))

    zf = jnp.zeros(w, dtype)
    st0 = (
        jnp.full(w, sentinel, jnp.int32),
        zf,
        jnp.full(w, -1, jnp.int32),
        zf,
        zf,
        jnp.full(w, no_tri, jnp.int32),
    )
    out0 = (jnp.full(n, jnp.inf, dtype), jnp.full(n, -1, jnp.int32), jnp.zeros(n, dtype), jnp.zeros(n, dtype))
    carry = refill((jnp.full(w, -1, jnp.int32), st0, jnp.asarray(0, jnp.int32), out0))
    _, _, _, (t, tri, u, v) = jax.lax.while_loop(cond, body, carry)
    t = jnp.where(tri >= 0, t, jnp.inf)
    if sort_rays:
        inv_perm = jnp.zeros_like(perm).at[perm].set(jnp.arange(n, dtype=jnp.int32))
        t, tri, u, v = t[inv_perm], tri[inv_perm], u[inv_perm], v[inv_perm]
    return t, tri, u, v
