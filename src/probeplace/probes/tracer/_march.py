"""Single-probe march of the light-field tracer (McGuire et al. 2017 §4.1 ``singleProbeTrace``; the
model — octant pieces, exact cell crossings, surfels, ambiguous cells, the hierarchy — is described in
``_trace``'s module docstring)."""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float, Int

from ..._core import norm3
from ._status import TraceStatus
from ._surfels import NEIGHBOURS, crease


def _levels(tr) -> tuple[int, int]:
    """(coarsest level the march uses, coarse level of the two-level scheme)."""
    top = tr.n_levels - 1
    cfg = tr.config
    coarse = min(int(math.log2(cfg.coarse_factor)), top)
    if cfg.hierarchy == "hiz":
        return max(top - cfg.hiz_skip_top, 0), coarse
    if cfg.hierarchy == "two_level":
        return coarse, coarse
    return 0, 0


class _Piece(NamedTuple):
    """One octant piece of a ray seen from a probe: the ray (probe-relative origin ``o``, direction
    ``d``), the octant's signs ``s``, the face numerators (u = a_u·q / s·q, v = a_v·q / s·q) and the signs
    ``du`` of the (monotone) motion of (u, v) along the piece."""

    o: Array
    d: Array
    s: Array
    a_u: Array
    a_v: Array
    du: Array


def _piece(o, d, ta, tb) -> _Piece:
    s = jnp.where(o + 0.5 * (ta + tb) * d >= 0, 1.0, -1.0).astype(o.dtype)
    lower = s[2] < 0
    one, zero = jnp.ones_like(s[0]), jnp.zeros_like(s[0])
    a_u = jnp.stack([one, zero, jnp.where(lower, s[0] * s[2], zero)])
    a_v = jnp.stack([zero, one, jnp.where(lower, s[1] * s[2], zero)])
    pc = _Piece(o, d, s, a_u, a_v, jnp.zeros(2, o.dtype))
    span = tb - ta
    du = jnp.sign(_uv_at(pc, tb - 1e-5 * span) - _uv_at(pc, ta + 1e-5 * span))
    return pc._replace(du=du)


def _uv_at(pc: _Piece, t):
    q = pc.o + t * pc.d
    l1 = jnp.maximum(jnp.dot(pc.s, q), jnp.finfo(q.dtype).tiny)
    return jnp.clip(jnp.stack([jnp.dot(pc.a_u, q), jnp.dot(pc.a_v, q)]) / l1, -1.0, 1.0)


def _cell_at(pc: _Piece, t, cells):
    """(row ↔ v, col ↔ u) of the cell containing the ray at t on a ``cells``² grid (nudged along the
    motion, so a point on a grid line is in the cell the ray enters)."""
    f = (_uv_at(pc, t) + 1.0) * (cells.astype(pc.o.dtype) * 0.5) + 1e-3 * pc.du
    return jnp.clip(jnp.floor(f).astype(jnp.int32), 0, cells - 1)[::-1]


def _grid_crossing(pc: _Piece, c, a):
    """t where the ray meets the plane (a − c·s)·q = 0 (the grid line at coordinate c), or inf."""
    w = a - c * pc.s
    den = jnp.dot(w, pc.d)
    ok = jnp.abs(den) > 1e-12
    t = jnp.where(ok, -jnp.dot(w, pc.o) / jnp.where(ok, den, 1.0), jnp.inf)
    return jnp.where(jnp.isfinite(t), t, jnp.inf)


def _cell_exit(pc: _Piece, ij, cells, t, tb, span):
    """(t where the ray leaves cell ``ij`` (at most tb), whether it leaves through a u line)."""
    dt = pc.o.dtype
    hcell = 2.0 / cells.astype(dt)
    lo = ij[::-1].astype(dt) * hcell - 1.0  # (u_lo, v_lo)
    c_next = jnp.where(pc.du > 0, lo + hcell, lo)
    t_u = jnp.where(pc.du[0] != 0, _grid_crossing(pc, c_next[0], pc.a_u), jnp.inf)
    t_v = jnp.where(pc.du[1] != 0, _grid_crossing(pc, c_next[1], pc.a_v), jnp.inf)
    # A root behind t is where the *extended* line would cross (u, v are monotone on the face, so the
    # march never meets it): never. Roots a rounding error behind t are "now".
    eps_t = 1e-5 * (jnp.abs(t) + span)
    t_u = jnp.where(t_u >= t - eps_t, jnp.maximum(t_u, t), jnp.inf)
    t_v = jnp.where(t_v >= t - eps_t, jnp.maximum(t_v, t), jnp.inf)
    return jnp.minimum(jnp.minimum(t_u, t_v), tb), t_u <= t_v


def _candidates(tr, ij):
    """Bordered (row, col) of the surfels a march cell's test reads: its texel's first, then the
    neighbours of its footprint (``_surfels``): 4 for ``subdivide`` = 2 (the 2×2 texels around the
    cell's corner), 9 for 1."""
    i0, j0 = ij[0] // tr.sub, ij[1] // tr.sub
    if tr.sub == 2:
        di, dj = 2 * (ij[0] % 2) - 1, 2 * (ij[1] % 2) - 1
        zero = jnp.zeros_like(di)
        off = jnp.stack(
            [jnp.stack([zero, zero]), jnp.stack([di, zero]), jnp.stack([zero, dj]), jnp.stack([di, dj])]
        )
    else:
        off = jnp.asarray([(0, 0), *NEIGHBOURS], jnp.int32)
    rows = jnp.clip(i0 + 1 + off[:, 0], 0, tr.res + 1)
    cols = jnp.clip(j0 + 1 + off[:, 1], 0, tr.res + 1)
    return rows, cols


def _partners(tr, xs, n, has):
    """Which candidate surfels bound a one-surface cell's free space: its own (candidate 0) and the
    footprint neighbours meeting it in a concave crease (``_surfels.crease``), whose surface is the nearer
    plane. With the own plane alone, a ray through a room's corner texel passes behind the floor while
    in front of the wall's plane and leaves the room as a false miss. A partner's plane crossed first is
    unknown, not a hit (``_surfel_test``): the crease test also passes some silhouettes (a pillar's side
    before a wall), where the partner plane runs through free space — on Sponza 16×8×8 at 64², taking
    those crossings as hits lowered the agreement with exact casting from 0.83 to 0.78.

    A neighbour whose normal is within θ of the own surfel's is no partner: across a texel (angular width
    Δ = √(4π)/res) the two planes part by at most r·Δ·tan θ, within half the surface shell when
    tan θ ≤ thickness / (2Δ) (47° at 512², 28° at 256², 8° at 64² with the 1.5 % shell), so the own plane
    stands for both as well as the shell allows. Neighbours on one flat wall pass the crease test (each
    surfel lies on the other's plane), and their planes, tilted by the rounding of the stored normals
    (bfloat16), are met a fraction of a millimetre apart: taking that for another surface crossed first
    left clear hits near the ray's origin unknown (found by the standalone reference,
    tests/probes/test_trace_simple.py). On Sponza's 16×8×8 grid at 512² (8,000 shading rays) the rule
    took the unresolved rays from 5.4 % to 3.2 % (among those whose origin a probe sees 4.2 → 2.6 %), the
    hits agreeing with exact casting 0.967 → 0.966."""
    own = jnp.arange(xs.shape[0]) == 0
    if tr.config.edge_tol is None:
        return own
    w = xs / jnp.maximum(jnp.linalg.norm(xs, axis=-1, keepdims=True), 1e-12)
    concave, _ = crease(xs[:1], n[:1], w[:1], xs, n, w, tr.config.edge_tol)
    u = n / jnp.maximum(jnp.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    tan_max = tr.config.thickness / (2.0 * math.sqrt(4.0 * math.pi) / tr.res)
    one_plane = u @ u[0] >= 1.0 / math.sqrt(1.0 + tan_max * tan_max)  # within θ of the own normal
    return own | (concave & ~one_plane & has & has[0])


def _edge_on(tr, xs0, o, d, t):
    """Whether the crossing at ``t`` lies farther (radially) from the cell's own surfel ``xs0`` than a
    plane seen at ``edge_on_deg`` from its normal spans between its texel's centre and the farthest point
    of a march cell (0.7 texel widths of √(4π)/res radians): ``TraceConfig.edge_on_deg``."""
    tol = math.tan(math.radians(tr.config.edge_on_deg)) * 0.7 * math.sqrt(4 * math.pi) / tr.res
    r_own = norm3(xs0)
    return jnp.abs(norm3(o + t * d) - r_own) > tol * r_own


def _surfel_test(tr, p, pc: _Piece, ij, t, t_exit):
    """The fine test of march cell ``ij`` over [t, t_exit] (module docstring): (status, t of the hit,
    geometry texel). Candidate 0 is the cell's own surfel; in an ambiguous cell every one counts."""
    o, d = pc.o, pc.d
    m = tr.march_res
    rows, cols = _candidates(tr, ij)
    w = tr.row[p]  # the probe's row of the per-probe maps
    xs, n, has = tr.surfels(w, rows, cols)
    ambiguous = tr.is_ambiguous(w, jnp.clip(ij[0], 0, m - 1), jnp.clip(ij[1], 0, m - 1))
    # Signed distances from each plane at the cell's ends, positive on the probe's side.
    g0 = jnp.sum(((o + t * d)[None, :] - xs) * n, axis=-1)
    g1 = jnp.sum(((o + t_exit * d)[None, :] - xs) * n, axis=-1)
    r_s = jnp.linalg.norm(xs, axis=-1)  # each surfel's distance from the probe
    tau = tr.config.thickness * r_s
    deeper = n @ d < 0
    cross_in = (g0 >= 0) & (g1 < 0)
    t_hit = jnp.where(cross_in, t + (t_exit - t) * g0 / jnp.where(cross_in, g0 - g1, 1.0), t)
    in_shell = (g0 < 0) & (g0 >= -tau)
    # The ray's origin is on the surfel's surface (TraceConfig.start_tol): behind its plane within the
    # thickness, or in front of it by no more than the plane's own error there.
    g_o = jnp.sum((o[None, :] - xs) * n, axis=-1)
    starts_here = (g_o >= -tau) & (g_o <= tr.config.start_tol * r_s)
    hit = has & (cross_in | (in_shell & deeper)) & ~starts_here
    # One surface: its own surfel decides. Ambiguous: free only in front of every candidate (bar the
    # surface the ray starts on, unless deep behind it); a hit only where every candidate is met at
    # about the same point (within the thickness); else unknown.
    blocks = has & ((~starts_here & ((g0 < 0) | (g1 < 0))) | (g0 < -tau))
    # Every candidate met, at nearly the same t (else the hit could be any of them): a hit.
    t_first = jnp.min(jnp.where(hit, t_hit, jnp.inf))
    t_last = jnp.max(jnp.where(hit, t_hit, -jnp.inf))
    all_hit = jnp.all(hit | starts_here) & jnp.any(~starts_here)
    all_hit = all_hit & (t_last - t_first <= tr.config.thickness * jnp.linalg.norm(o + t_first * d))
    # Not where the ray is already deep behind a candidate (one it starts on): the cell's upper bound
    # (``_surfels``), which the march read here until the finest level's bounds were dropped, says unknown.
    all_hit = all_hit & ~jnp.any(has & (g0 < -tau))
    t_amb = jnp.where(hit[0], t_hit[0], t_first)
    if tr.config.edge_on_deg is not None:
        # As for one surface below, against the cell's own surfel, and against every surfel whose plane
        # is met: at a silhouette a nearer surface's plane, extended across the cell, is met far behind
        # its own surfel while the cell's own (a floor the ray starts on: ``starts_here``) says nothing.
        # On Sponza (skeleton, 54 probes) one probe's such hits, 1–9 cm above the floor, made 72 % of the
        # glossy error over the perfect trace.
        met_far = jax.vmap(lambda x, th: _edge_on(tr, x, o, d, th))(xs, t_hit)
        far_off = _edge_on(tr, xs[0], o, d, t_amb) | jnp.any(hit & met_far)
        blocks = blocks | (all_hit & far_off)
        all_hit = all_hit & ~far_off
    several = jnp.where(
        all_hit, TraceStatus.HIT, jnp.where(jnp.any(blocks), TraceStatus.UNKNOWN, TraceStatus.MISS)
    )
    # One surface: its own surfel decides a hit; a concave-crease partner's plane (``_partners``) crossed
    # first, or the ray starting deep behind either, is unknown from the cell's entry — the crease may be
    # a corner (the partner is the surface there) or a silhouette taken for one (it is not): another probe
    # decides.
    partner = _partners(tr, xs, n, has)
    t_partner = jnp.min(jnp.where(hit & partner & (jnp.arange(hit.shape[0]) > 0), t_hit, jnp.inf))
    own_first = hit[0] & (t_hit[0] <= t_partner * (1 + 1e-3))
    blocked = jnp.isfinite(t_partner) | jnp.any(partner & has & (g0 < -tau))
    if tr.config.edge_on_deg is not None:
        # The own plane crossed far from the surfel's distance: seen nearly edge-on, where one plane per
        # texel does not fit the geometry (TraceConfig.edge_on_deg). Unknown from the cell's entry.
        edge_on = _edge_on(tr, xs[0], o, d, t_hit[0])
        blocked = blocked | (own_first & edge_on)
        own_first = own_first & ~edge_on
    one = jnp.where(own_first, TraceStatus.HIT, jnp.where(blocked, TraceStatus.UNKNOWN, TraceStatus.MISS))
    status = jnp.where(ambiguous, several, one).astype(jnp.int32)
    texel = jnp.stack([rows[0], cols[0]]) - 1
    return status, jnp.where(ambiguous, t_amb, jnp.where(one == TraceStatus.HIT, t_hit[0], t)), texel


def _next_cell(tr, pc: _Piece, level, ij, ij_adv, advance, t, at_start):
    """Level and cell of the next step: after an advance, hi-Z climbs one level once the ray has left
    the parent cell, two-level climbs back to the coarse level on leaving the coarse cell; on a possible
    hit, descend (hi-Z one level — straight to the finest while still at the trace's start, which lies on
    a surface or next to the one that stopped the previous probe —, two-level to the finest)."""
    cfg = tr.config
    top, coarse = _levels(tr)
    at_fine = level == 0
    if cfg.hierarchy == "hiz":
        leaves = jnp.any(jnp.right_shift(ij_adv, 1) != jnp.right_shift(ij, 1))
        up = jnp.where(leaves, jnp.minimum(level + 1, top), level)
        down = jnp.where(at_start, 0, jnp.maximum(level - 1, 0))
    elif cfg.hierarchy == "two_level":
        shift = jnp.int32(coarse)
        leaves = jnp.any(jnp.right_shift(ij_adv, shift) != jnp.right_shift(ij, shift))
        up = jnp.where(at_fine & leaves & (coarse > 0), jnp.int32(coarse), level)
        down = jnp.int32(0)
    else:
        up = down = jnp.int32(0)
    ij_up = jnp.right_shift(ij_adv, up - level)
    ij_down = _cell_at(pc, t, jnp.right_shift(jnp.int32(tr.march_res), down))
    ij_down = jnp.clip(ij_down, jnp.left_shift(ij, level - down), jnp.left_shift(ij + 1, level - down) - 1)
    level_new = jnp.where(advance, up, jnp.where(at_fine, level, down))
    ij_new = jnp.where(advance, ij_up, jnp.where(at_fine, ij, ij_down))
    return level_new, ij_new


def _march_step(tr, p, pc: _Piece, tb, span, t_min, c):
    """ONE march step of an octant piece [ta, tb] (``span`` = tb − ta) in probe ``p``, whose single-probe
    trace began at ``t_min``: test the current cell (skip, deep or the fine surfel test, by level) and
    move to the next cell or level. ``c`` = (status, t, steps, texel, level, ij); returns it updated.
    The per-ray march (:func:`_trace_segment`) and the wavefront tracer (``_wavefront``) both step with
    it, so they give the same answers."""
    m = tr.march_res
    offsets = jnp.asarray([tr.level_offset(k) for k in range(tr.n_levels)], jnp.int32)
    o, d = pc.o, pc.d
    _status, t, steps, texel, level, ij = c
    cells = jnp.right_shift(jnp.int32(m), level)
    t_exit, step_u = _cell_exit(pc, ij, cells, t, tb, span)
    # Above the finest level (whose bounds are not stored, ``_trace._cell_maps``: there the fine test
    # decides alone), skip test: the whole cell's ray interval in front of every candidate surfel's lower
    # bound? Deep test: the ray, where it is now, beyond every fine cell's upper bound (behind them all)?
    at_fine = level == 0
    flat = jnp.where(at_fine, 0, offsets[level] + ij[0] * cells + ij[1])
    rho_t = jnp.linalg.norm(o + t * d)
    skip = jnp.maximum(rho_t, jnp.linalg.norm(o + t_exit * d)) < tr.lower(tr.row[p], flat)
    deep = ~at_fine & (rho_t > tr.upper(tr.row[p], flat))
    fine, t_hit, fine_texel = _surfel_test(tr, p, pc, ij, t, t_exit)
    fine_texel = jnp.where(at_fine, fine_texel, _cell_at(pc, t, jnp.int32(m)) // tr.sub)
    status = jnp.where(
        deep, jnp.int32(TraceStatus.UNKNOWN), jnp.where(at_fine, fine, jnp.int32(TraceStatus.MISS))
    )
    advance = jnp.where(at_fine, status == TraceStatus.MISS, skip & ~deep)
    step = jnp.where(step_u, jnp.array([0, 1], jnp.int32), jnp.array([1, 0], jnp.int32))
    ij_adv = ij + step * jnp.where(step_u, pc.du[0], pc.du[1]).astype(jnp.int32)
    level_new, ij_new = _next_cell(tr, pc, level, ij, ij_adv, advance, t, t <= t_min)
    t_new = jnp.where(advance, t_exit, jnp.where(status == TraceStatus.HIT, t_hit, t))
    texel_new = jnp.where(status != TraceStatus.MISS, fine_texel, texel)
    # Left the face (numerically) before tb: end the piece.
    out = jnp.any((ij_new < 0) | (ij_new >= jnp.right_shift(jnp.int32(m), level_new)))
    t_new = jnp.where(out & (status == TraceStatus.MISS), tb, t_new)
    return status, t_new, steps + 1, texel_new, level_new, ij_new


def _segment_go(tr, status, ta, tb):
    """Whether an octant piece [ta, tb] is marched at all: the probe's trace is still free (MISS) and the
    piece is not a numerically empty sliver."""
    return (status == TraceStatus.MISS) & (tb - ta > 1e-6 * tr.t_far)


def _segment_start(tr, o, d, ta, tb, state):
    """Set up the march of one octant piece [ta, tb] of the ray (probe-relative origin ``o``), continuing
    the single-probe ``state`` = (status, t, steps, texel).

    Returns:
        (piece, span, go, step budget, march carry (status, t, steps, texel, level, ij)).
    """
    m = tr.march_res
    top, _ = _levels(tr)
    max_steps = tr.config.max_steps or 6 * m
    pc = _piece(o, d, ta, tb)
    span = tb - ta
    status, t, steps, texel = state
    start = jnp.maximum(t, ta)
    go = _segment_go(tr, status, ta, tb)
    seg_steps = steps + max_steps  # the step budget is per octant piece
    level0 = jnp.int32(top)
    if tr.config.hierarchy == "hiz":
        # Start where the piece spans a cell or two (its extent on the map in finest cells), not at the
        # top: a short piece would otherwise descend through levels it never needed.
        extent = jnp.max(jnp.abs(_uv_at(pc, tb) - _uv_at(pc, start))) * (m / 2.0)
        fit = jnp.floor(jnp.log2(jnp.maximum(extent, 1.0))).astype(jnp.int32)
        level0 = jnp.clip(fit, 0, top)
    cells0 = jnp.right_shift(jnp.int32(m), level0)
    return pc, span, go, seg_steps, (status, start, steps, texel, level0, _cell_at(pc, start, cells0))


def _segment_running(go, tb, seg_steps, c):
    """Whether the march of a piece takes another step (``c``: the march carry)."""
    status, t, steps = c[0], c[1], c[2]
    return go & (status == TraceStatus.MISS) & (t < tb) & (steps < seg_steps)


def _segment_end(go, tb, seg_steps, c, state):
    """The single-probe state after the march of a piece stopped (``state``: the state it started from)."""
    status, t, steps, texel = c[:4]
    # Running out of steps inside the piece is "unknown" (the ray is not known to be free beyond t).
    status = jnp.where(
        go & (status == TraceStatus.MISS) & (t < tb) & (steps >= seg_steps), TraceStatus.UNKNOWN, status
    )
    t = jnp.where(go, t, state[1])
    return status, t, steps, texel


def _trace_segment(tr, p, o, d, ta, tb, t_min, state):
    """March one octant piece [ta, tb] of the ray (probe-relative origin ``o``) in probe ``p``; the
    single-probe trace began at ``t_min``.

    ``state`` = (status, t, steps, texel); returns it updated. Continues only while status == MISS.
    """
    pc, span, go, seg_steps, init = _segment_start(tr, o, d, ta, tb, state)

    def cond(c):
        # No lax.cond around the loop: under vmap a batched predicate would batch every closed-over map.
        return _segment_running(go, tb, seg_steps, c)

    out = jax.lax.while_loop(cond, lambda c: _march_step(tr, p, pc, tb, span, t_min, c), init)
    return _segment_end(go, tb, seg_steps, out, state)


def _probe_pieces(tr, p, origin, direction, t_min, t_max):
    """(probe-relative origin, bounds (5,) of the ≤ 4 octant pieces of [t_min, t_max]: the ray split at
    the probe's three coordinate planes, McGuire 2017 §4.1)."""
    o = origin - tr.pos_world[p]
    dt = o.dtype
    safe_d = jnp.where(jnp.abs(direction) > 1e-12, direction, 1e-12)
    tc = jnp.sort(jnp.clip(-o / safe_d, t_min, t_max))
    return o, jnp.concatenate([t_min[None], tc, t_max[None]]).astype(dt)


def _probe_state(t_min):
    """A single-probe trace's state before its first piece: (status MISS, t, steps, texel)."""
    return jnp.int32(TraceStatus.MISS), t_min, jnp.int32(0), jnp.zeros(2, jnp.int32)


def trace_probe(
    tr,
    p: Int[Array, ""],
    origin: Float[Array, "3"],
    direction: Float[Array, "3"],
    t_min: Float[Array, ""],
    t_max: Float[Array, ""],
) -> tuple[Int[Array, ""], Float[Array, ""], Int[Array, ""], Int[Array, "2"]]:
    """Single-probe trace of ONE ray over [t_min, t_max] (McGuire 2017 §4.1, Listing 1 ``singleProbeTrace``).

    Args:
        tr: the tracer (``LightFieldTracer``).
        p: probe row.
        origin, direction: the ray, world frame; ``direction`` unit length.
        t_min, t_max: the segment to march.

    Returns:
        (status MISS=0 / HIT=1 / UNKNOWN=2, t of the hit or of the last point the probe saw free (t_max on
        a miss), march steps, geometry texel (row, col) of the hit or of the unknown).
    """
    o, bounds = _probe_pieces(tr, p, origin, direction, t_min, t_max)

    def seg(k, st):
        return _trace_segment(tr, p, o, direction, bounds[k], bounds[k + 1], t_min, st)

    status, t, steps, texel = jax.lax.fori_loop(0, 4, seg, _probe_state(t_min))
    t = jnp.where(status == TraceStatus.MISS, t_max, t)
    return status, t, steps, texel
