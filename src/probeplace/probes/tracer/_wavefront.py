"""Wavefront engine of the light-field tracer: the per-ray algorithm of ``_trace`` (McGuire et al. 2017
Listing 1; single-probe march of ``_march``) run as a state machine over a fixed-size batch of lanes.

**Why.** The per-ray engine vmaps nested ``while_loop``s (probes → octant pieces → march steps); under
vmap every loop runs until its slowest lane, so few executed lane-steps do work (≈ 4% on the Cornell
box), and the whole batch waits for its slowest ray. Here each lane holds ONE ray's state — the
many-probe loop's (``_RayState``), the probe being traced (its octant pieces), the piece being marched
(its ``_Piece`` and march carry) and a *phase* (idle, select, piece, march, done) — and every lane takes
the same single step (:func:`_step`): the "wavefront" organisation of GPU path tracers (Laine, Karras &
Aila 2013, "Megakernels considered harmful: wavefront path tracing on GPUs"). A step is

1. *select*: lanes that need a probe run the index's pick (``_pick_index``); those whose index is spent
   run the search for probes that see the last free point (``_seeing_probe``); the probe is chosen
   (``_pick``) and split into octant pieces (``_probe_pieces``). The pick reads 8 candidates' surfels,
   the search 32: each costs several march steps, and per step only a few percent of the lanes need
   them (measured: 5% / 0.1% on the Cornell box, 23% / 3% on Sponza), so they run on the lanes that need
   them only, gathered a block at a time (:func:`_serve`), not masked over the batch;
2. *piece start* (``_segment_start``) for a new probe's first non-empty piece or the next piece;
3. *march*: one ``_march_step`` for every marching lane (a lane that started a piece marches at once);
4. *piece end* (``_segment_end``): the next non-empty piece, or the end of the probe;
5. *probe end* (``_after_probe``): the ray goes on to another probe, or is done.

Every ``wavefront_steps`` steps the finished rays are written out and their lanes refilled from the queue
of rays not yet started, so lanes stay busy. Once the queue is empty and few rays are left, the live lanes
are compacted into a batch an eighth the size, so the last slow rays do not hold the full batch. Shapes
are static (lanes, blocks, stages), so one compile serves every call with the same number of rays. The
queue is sorted by the index cell of each ray's origin and its direction's octant, so neighbouring lanes
read the same probes' maps.

**Same answers.** A lane goes through exactly the per-ray engine's sequence of states, through the same
functions (``_march``: ``_segment_start`` / ``_march_step`` / ``_segment_running`` / ``_segment_end`` /
``_probe_pieces``; ``_trace``: ``_pick_index`` / ``_seeing_probe`` / ``_pick`` / ``_after_probe`` /
``_ray_result``); scheduling decides only *when* a lane steps, never what a step computes. Status, probe,
texel, march steps, probes tried and fallback count are therefore identical. ``t`` agrees to a few ulps
of the probe-relative coordinates, not bit for bit: XLA fuses the same float32 expressions differently
in the two programs and LLVM contracts multiply–adds into FMAs per fusion — the per-ray engine differs
from itself as much between two batch sizes (tests/probes/test_wavefront.py).

Choose the engine with ``TraceConfig(engine="wavefront")``; :func:`~._engine.trace_light_field` then runs
:func:`trace_wavefront`. The per-ray engine stays the library's default; both are held to the
standalone NumPy reference (``_simple.trace_probe_simple``).
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from ..._core import take_queued, write_finished
from ._index import GridIndex
from ._march import (
    _march_step,
    _Piece,
    _probe_pieces,
    _probe_state,
    _segment_end,
    _segment_go,
    _segment_running,
    _segment_start,
)
from ._status import TraceStatus
from ._trace import (
    LightFieldTracer,
    TraceResult,
    _after_probe,
    _lookback,
    _pick,
    _pick_index,
    _ray_result,
    _ray_state,
    _ray_t_end,
    _RayState,
    _seeing_probe,
    _wants_fallback,
)

#: Lane phases.
IDLE, SELECT, PIECE, MARCH, DONE = 0, 1, 2, 3, 4
#: The tail stage runs 1/_TAIL of the lanes, and only if that is at least _MIN_LANES.
_TAIL, _MIN_LANES = 8, 16


class WavefrontStats(eqx.Module):
    """How the wavefront engine spent its steps.

    Attributes:
        chunks: chunks of ``wavefront_steps`` steps run by each stage (batch sizes ``lanes``).
        lanes: the stages' batch sizes (static).
        steps_per_chunk: ``wavefront_steps`` (static).
    """

    chunks: Int[Array, " n_stages"]
    lanes: tuple[int, ...] = eqx.field(static=True)
    steps_per_chunk: int = eqx.field(static=True)

    def lane_steps(self) -> int:
        """Executed lane-steps (every lane of every step, busy or not); host-side Python int."""
        chunks = np.asarray(self.chunks)
        return int(sum(int(c) * b for c, b in zip(chunks, self.lanes, strict=True))) * self.steps_per_chunk


class _Lanes(NamedTuple):
    """The batch: one ray per lane (``ray`` -1: idle). Fields after ``rs`` describe the pick, the probe
    and the octant piece in progress (see the module docstring)."""

    ray: Array  # (B,) ray id
    phase: Array  # (B,)
    origin: Array  # (B, 3)
    direction: Array  # (B, 3)
    t_end: Array  # (B,)
    rs: _RayState  # the many-probe loop's state
    x: Array  # (B, 3) point where the unresolved part starts (pick in progress)
    p_idx: Array  # index's candidate (pick in progress)
    from_index: Array
    cell: Array
    slot: Array
    p: Array  # probe being traced
    found: Array
    from_fb: Array
    o: Array  # (B, 3) probe-relative origin
    bounds: Array  # (B, 5) octant pieces
    k: Array  # piece being marched
    s: Array  # (B, 3) the piece (``_Piece``: s, a_u, a_v, du)
    a_u: Array
    a_v: Array
    du: Array  # (B, 2)
    span: Array
    go: Array
    seg_steps: Array
    carry: tuple  # march carry (status, t, steps, texel, level, ij); its first four: the probe's state


def _where(mask, new, old):
    """Lane-wise select over pytrees of (B, ...) arrays."""

    def one(a, b):
        m = mask.reshape(mask.shape + (1,) * (a.ndim - 1))
        return jnp.where(m, a, b)

    return jax.tree_util.tree_map(one, new, old)


def _take(tree, idx):
    """Rows ``idx`` of every leaf (out-of-range rows: clamped; their results are dropped by :func:`_put`)."""
    return jax.tree_util.tree_map(lambda a: jnp.take(a, idx, axis=0, mode="clip"), tree)


def _put(tree, idx, rows):
    """Write ``rows`` into rows ``idx`` of every leaf (out-of-range rows dropped)."""
    return jax.tree_util.tree_map(lambda a, r: a.at[idx].set(r.astype(a.dtype), mode="drop"), tree, rows)


def _next_piece(tr: LightFieldTracer, bounds, k0, status):
    """The first piece ≥ ``k0`` that the per-ray march would march (``_segment_go``), or 4 (none): the
    per-ray engine's empty pieces take no step, so the wavefront skips them at once."""
    ks = jnp.arange(4, dtype=jnp.int32)
    go = jax.vmap(lambda a, b: _segment_go(tr, status, a, b))(bounds[:4], bounds[1:]) & (ks >= k0)
    return jnp.where(jnp.any(go), jnp.argmax(go).astype(jnp.int32), jnp.int32(4))


def _choose(tr: LightFieldTracer, origin, direction, t_end, rs: _RayState, p_idx, from_index, p_fb):
    """Rows of lanes whose pick is complete (the index's ``p_idx``, the fallback search's ``p_fb``): the
    probe to trace (``_pick``), its octant pieces over the ray's unresolved part [t, t_end] and the first
    non-empty one."""

    def one(origin, direction, t_end, rs, p_idx, from_index, p_fb):
        p, found, from_fb = _pick(tr, p_idx, from_index, p_fb, rs)
        o, bounds = _probe_pieces(tr, jnp.maximum(p, 0), origin, direction, rs.t, t_end)
        k = _next_piece(tr, bounds, jnp.int32(0), jnp.int32(TraceStatus.MISS))
        return dict(p=p, found=found, from_fb=from_fb, o=o, bounds=bounds, k=k)

    return jax.vmap(one)(origin, direction, t_end, rs, p_idx, from_index, p_fb)


def _serve(need, block: int, fn, outs):
    """Run ``fn`` on the lanes where ``need``, ``block`` lanes at a time, and write its rows into
    ``outs`` (a pytree of (B, ...) arrays). The loop runs as many times as the demand needs, so an
    expensive stage costs in proportion to the lanes that need it, not to the batch."""
    b = need.shape[0]
    padded = -(-b // block) * block
    idx = jnp.nonzero(need, size=padded, fill_value=b)[0]
    count = jnp.sum(need, dtype=jnp.int32)

    def body(c):
        i, outs = c
        rows = jax.lax.dynamic_slice(idx, (i * block,), (block,))
        return i + 1, _put(outs, rows, fn(rows))

    return jax.lax.while_loop(lambda c: c[0] * block < count, body, (jnp.int32(0), outs))[1]


def _fallback_search(tr: LightFieldTracer, lanes: _Lanes, select, block_fb: int) -> _Lanes:
    """Step 1b: lanes whose index is spent pick among the probes that see the last free point."""
    to_fb = select & jax.vmap(lambda f, c: _wants_fallback(tr, f, c))(lanes.from_index, lanes.rs)

    def fallback_rows(idx):
        picked = (lanes.x, lanes.p_idx, lanes.from_index)
        x, p_idx, from_index = _take(picked, idx)
        origin, direction, t_end, rs = _take((lanes.origin, lanes.direction, lanes.t_end, lanes.rs), idx)
        x_back = jax.vmap(lambda o, d, t: _lookback(tr, o, d, t))(origin, direction, rs.t)
        p_fb = jax.vmap(lambda x, xb, v: _seeing_probe(tr, x, xb, v))(x, x_back, rs.visited)
        return _choose(tr, origin, direction, t_end, rs, p_idx, from_index, p_fb)

    keys_fb = ("p", "found", "from_fb", "o", "bounds", "k")
    with jax.named_scope("wf_fallback"):
        return lanes._replace(
            **_serve(to_fb, block_fb, fallback_rows, {k: getattr(lanes, k) for k in keys_fb})
        )


def _select(tr: LightFieldTracer, lanes: _Lanes, block: int, block_fb: int):
    """Step 1: pick a probe for every lane that needs one and split it into octant pieces.

    Returns ``(lanes, fresh, end_probe)``: ``fresh`` marks lanes with a new probe to march (its march
    carry reset), ``end_probe`` lanes whose pick left nothing to march.
    """
    # 1. Select: the index's pick for every lane that needs a probe, then the search for probes that see
    # x for those whose index is spent; each decides the probe and its pieces (``_choose``). Both run
    # only where needed (``_serve``).
    select = lanes.phase == SELECT
    use_fb = tr.config.fallback_probes > 0
    keys = ("x", "p_idx", "cell", "slot", "from_index", "p", "found", "from_fb", "o", "bounds", "k")

    def pick_rows(idx):
        origin, direction, t_end, rs = _take((lanes.origin, lanes.direction, lanes.t_end, lanes.rs), idx)
        x, p_idx, cell, slot, from_index = jax.vmap(lambda *a: _pick_index(tr, *a))(origin, direction, rs)
        # Lanes bound for the fallback search are decided there; -1 stands for its pick meanwhile.
        chosen = _choose(tr, origin, direction, t_end, rs, p_idx, from_index, jnp.full_like(p_idx, -1))
        return dict(x=x, p_idx=p_idx, cell=cell, slot=slot, from_index=from_index, **chosen)

    with jax.named_scope("wf_pick"):
        lanes = lanes._replace(**_serve(select, block, pick_rows, {k: getattr(lanes, k) for k in keys}))
    if use_fb:
        lanes = _fallback_search(tr, lanes, select, block_fb)
    fresh = select & lanes.found & (lanes.k < 4)
    probe0 = (*jax.vmap(_probe_state)(lanes.rs.t), *lanes.carry[4:])
    lanes = lanes._replace(carry=_where(fresh, probe0, lanes.carry))
    # A probe with nothing to march (none found, or every piece empty) ends at once.
    end_probe = select & ~fresh
    return lanes, fresh, end_probe


def _piece_start(tr: LightFieldTracer, lanes: _Lanes, rows, fresh):
    """Step 2: start the piece of lanes with a fresh probe or a finished piece; returns (lanes, start, tb)."""
    # 2. Piece start: a new probe's first piece, or the next piece of the previous step's probe.
    start = fresh | (lanes.phase == PIECE)
    ta = lanes.bounds[rows, jnp.minimum(lanes.k, 3)]
    tb = lanes.bounds[rows, jnp.minimum(lanes.k + 1, 4)]
    with jax.named_scope("wf_piece_start"):
        pc, span, go, seg_steps, init = jax.vmap(lambda *a: _segment_start(tr, *a))(
            lanes.o, lanes.direction, ta, tb, lanes.carry[:4]
        )
    new = dict(s=pc.s, a_u=pc.a_u, a_v=pc.a_v, du=pc.du, span=span, go=go, seg_steps=seg_steps, carry=init)
    lanes = lanes._replace(**_where(start, new, {k: getattr(lanes, k) for k in new}))
    return lanes, start, tb


def _march(tr: LightFieldTracer, lanes: _Lanes, start, tb):
    """Step 3: one march step for every marching lane; returns (new march carry, marching mask)."""
    # 3. March (a lane that started its piece above marches in the same step).
    marching = start | (lanes.phase == MARCH)
    pc = _Piece(lanes.o, lanes.direction, lanes.s, lanes.a_u, lanes.a_v, lanes.du)
    running = marching & jax.vmap(_segment_running)(lanes.go, tb, lanes.seg_steps, lanes.carry)
    with jax.named_scope("wf_march"):
        stepped = jax.vmap(lambda *a: _march_step(tr, *a))(
            lanes.p, pc, tb, lanes.span, lanes.rs.t, lanes.carry
        )
    return _where(running, stepped, lanes.carry), marching


def _piece_end(tr: LightFieldTracer, lanes: _Lanes, carry, marching, tb):
    """Step 4: close the pieces that stopped; returns (lanes, ended, last_piece) for the probe's end."""
    # 4. Piece end: the next non-empty piece (started next step), or the probe's end. ``go`` is true for
    # every piece a lane marches (``_next_piece``), so the state the piece started from is not needed.
    ended = marching & ~jax.vmap(_segment_running)(lanes.go, tb, lanes.seg_steps, carry)
    with jax.named_scope("wf_piece_end"):
        state = jax.vmap(_segment_end)(lanes.go, tb, lanes.seg_steps, carry, carry[:4])
        k_next = jax.vmap(lambda *a: _next_piece(tr, *a))(lanes.bounds, lanes.k + 1, state[0])
    lanes = lanes._replace(
        carry=_where(ended, (*state, *carry[4:]), carry), k=jnp.where(ended, k_next, lanes.k)
    )
    return lanes, ended, ended & (k_next >= 4)


def _probe_end(tr: LightFieldTracer, lanes: _Lanes, marching, ended, end_probe) -> _Lanes:
    """Step 5: the many-probe loop's update for lanes whose probe ended, and every lane's next phase."""
    # 5. Probe end: the many-probe loop's update; the ray continues (another probe) or is done.
    pst, pt, psteps, ptexel = lanes.carry[:4]
    probe_out = (
        pst,
        jnp.where(pst == TraceStatus.MISS, lanes.t_end, pt),
        psteps,
        ptexel,
    )  # as ``trace_probe``
    with jax.named_scope("wf_probe_end"):
        rs = jax.vmap(lambda *a: _after_probe(tr, *a))(
            lanes.rs,
            lanes.p,
            lanes.found,
            lanes.from_index,
            lanes.from_fb,
            lanes.cell,
            lanes.slot,
            probe_out,
            lanes.origin + lanes.t_end[:, None] * lanes.direction,
        )
    phase = jnp.where(marching, jnp.where(ended, jnp.int32(PIECE), jnp.int32(MARCH)), lanes.phase)
    phase = jnp.where(
        end_probe, jnp.where(rs.st == TraceStatus.UNKNOWN, jnp.int32(SELECT), jnp.int32(DONE)), phase
    )
    return lanes._replace(rs=_where(end_probe, rs, lanes.rs), phase=phase)


def _step(tr: LightFieldTracer, lanes: _Lanes, block: int, block_fb: int) -> _Lanes:
    """ONE step of every lane (module docstring); the index's pick runs ``block`` lanes at a time, the
    fallback search ``block_fb``."""
    b = lanes.ray.shape[0]
    rows = jnp.arange(b)
    lanes, fresh, end_probe = _select(tr, lanes, block, block_fb)
    lanes, start, tb = _piece_start(tr, lanes, rows, fresh)
    carry, marching = _march(tr, lanes, start, tb)
    lanes, ended, last_piece = _piece_end(tr, lanes, carry, marching, tb)
    end_probe = end_probe | last_piece
    return _probe_end(tr, lanes, marching, ended, end_probe)


class _Out(NamedTuple):
    """Results of finished rays, by ray id (row n: the sink for idle lanes)."""

    status: Array
    t: Array
    probe: Array
    texel: Array
    steps: Array
    probes_tried: Array
    fallback: Array


def _flush(tr, lanes: _Lanes, out: _Out) -> tuple[_Lanes, _Out]:
    """Write finished rays out and mark their lanes idle."""
    n = out.status.shape[0] - 1
    done = lanes.phase == DONE
    res = jax.vmap(_ray_result)(lanes.rs)
    out = _Out(*write_finished(tuple(out), done, lanes.ray, tuple(res), n))  # idle lanes: sink row n
    return lanes._replace(ray=jnp.where(done, -1, lanes.ray), phase=jnp.where(done, IDLE, lanes.phase)), out


def _refill(tr, lanes: _Lanes, queue, qptr):
    """Give idle lanes the next rays of the queue (``queue`` = (order, origins, directions, t_end))."""
    order, origins, directions, t_end = queue
    n = order.shape[0]
    pos, take, qptr = take_queued(lanes.phase == IDLE, qptr, n)  # the shared scheduler (_core.maths._lanes)
    ray = jnp.take(order, jnp.maximum(pos, 0))
    rs0 = jax.vmap(lambda _: _ray_state(tr, origins.dtype))(ray)
    new = dict(
        ray=ray,
        phase=jnp.full_like(lanes.phase, SELECT),
        origin=origins[ray],
        direction=directions[ray],
        t_end=t_end[ray],
        rs=rs0,
    )
    lanes = lanes._replace(**_where(take, new, {k: getattr(lanes, k) for k in new}))
    return lanes, qptr


def _empty_lanes(tr: LightFieldTracer, b: int, dtype) -> _Lanes:
    """A batch of ``b`` idle lanes."""
    z = lambda *s: jnp.zeros((b, *s), dtype)
    zi = lambda *s: jnp.zeros((b, *s), jnp.int32)
    zb = lambda *s: jnp.zeros((b, *s), bool)
    rs = jax.vmap(lambda _: _ray_state(tr, dtype))(jnp.arange(b))
    return _Lanes(
        ray=-jnp.ones(b, jnp.int32),
        phase=zi(),
        origin=z(3),
        direction=z(3),
        t_end=z(),
        rs=rs,
        x=z(3),
        p_idx=zi(),
        from_index=zb(),
        cell=zi(),
        slot=zi(),
        p=zi(),
        found=zb(),
        from_fb=zb(),
        o=z(3),
        bounds=z(5),
        k=zi(),
        s=z(3),
        a_u=z(3),
        a_v=z(3),
        du=z(2),
        span=z(),
        go=zb(),
        seg_steps=zi(),
        carry=(zi(), z(), zi(), zi(2), zi(), zi(2)),
    )


def _stage_sizes(tr: LightFieldTracer, n: int) -> tuple[int, ...]:
    """Batch sizes of the stages: the configured lanes (no more than the rays, rounded up to 8), then an
    eighth of that for the tail (unless below ``_MIN_LANES``). Each stage compiles the step anew (about
    10 s on two CPU cores), so there are only two: the tail stage saves ≈ 15% of the lane-steps."""
    b = min(tr.config.wavefront_lanes, -(-n // 8) * 8)
    return (b, b // _TAIL) if b // _TAIL >= _MIN_LANES else (b,)


def _queue_order(tr: LightFieldTracer, origins, directions):
    """Ray ids sorted by the index cell of the origin, then the direction's octant (local gathers)."""
    if isinstance(tr.index, GridIndex):
        cell = jax.vmap(lambda x: tr.index.cage(x)[1])(origins)
    else:
        cell = jax.vmap(lambda x: tr.index.lookup(x)[1])(origins)
    bits = jnp.asarray([[1, 2, 4]], jnp.int32)
    octant = jnp.sum((directions >= 0).astype(jnp.int32) * bits, axis=1, dtype=jnp.int32)
    return jnp.argsort(cell.astype(jnp.int32) * 8 + octant, stable=True).astype(jnp.int32)


@eqx.filter_jit
def trace_wavefront(
    tr: LightFieldTracer,
    origins: Float[Array, "n_rays 3"],
    directions: Float[Array, "n_rays 3"],
    t_max: Float[Array, " n_rays"] | None = None,
) -> tuple[TraceResult, WavefrontStats]:
    """Trace a batch of rays with the wavefront engine (module docstring); same answers as the per-ray
    engine. Batch sizes and chunk length come from ``tr.config`` (``wavefront_lanes``,
    ``wavefront_steps``).

    Args:
        tr: from :func:`~._trace.make_tracer`.
        origins: ray origins, world frame.
        directions: unit directions.
        t_max: optional per-ray maximum distance (default: the scene diagonal).

    Returns:
        (:class:`~._trace.TraceResult`, :class:`WavefrontStats`). Not differentiable.
    """
    dt = tr.pos_world.dtype
    origins = jnp.asarray(origins, dt)
    directions = jnp.asarray(directions, dt)
    n = origins.shape[0]
    if t_max is None:
        t_max = jnp.full((n,), jnp.inf, dt)
    t_max = jnp.asarray(t_max, dt)
    if n == 0:
        z = jnp.zeros(0, jnp.int32)
        empty = TraceResult(z, jnp.zeros(0, dt), z, jnp.zeros((0, 2), jnp.int32), z, z, z)
        return empty, WavefrontStats(chunks=jnp.zeros(0, jnp.int32), lanes=(), steps_per_chunk=0)
    t_end = jax.vmap(lambda o, d, m: _ray_t_end(tr, o, d, m))(origins, directions, t_max)
    queue = (_queue_order(tr, origins, directions), origins, directions, t_end)
    out = _Out(
        status=jnp.zeros(n + 1, jnp.int32),
        t=jnp.zeros(n + 1, dt),
        probe=jnp.zeros(n + 1, jnp.int32),
        texel=jnp.zeros((n + 1, 2), jnp.int32),
        steps=jnp.zeros(n + 1, jnp.int32),
        probes_tried=jnp.zeros(n + 1, jnp.int32),
        fallback=jnp.zeros(n + 1, jnp.int32),
    )
    sizes = _stage_sizes(tr, n)
    k_steps = tr.config.wavefront_steps
    chunks = []
    lanes = None
    qptr = jnp.int32(0)
    for si, b in enumerate(sizes):
        # Sub-batches sized to the demand measured on the Cornell box and Sponza (per step, about 5% and
        # 23% of the lanes need a probe, 0.1% and 3% the fallback search): a block's unused rows cost as
        # much as used ones.
        block, block_fb = max(b // 32, 1), max(b // 64, 1)
        if lanes is None:
            lanes = _empty_lanes(tr, b, dt)
        else:  # compact: the live lanes (at most b of them, by the previous stage's exit test)
            live = jnp.nonzero(lanes.phase != IDLE, size=b, fill_value=lanes.ray.shape[0])[0]
            keep = jnp.arange(b, dtype=jnp.int32) < jnp.sum(lanes.phase != IDLE, dtype=jnp.int32)
            small = _take(lanes, live)
            lanes = small._replace(
                ray=jnp.where(keep, small.ray, -1), phase=jnp.where(keep, small.phase, IDLE)
            )
        nxt = sizes[si + 1] if si + 1 < len(sizes) else 0

        def cond(c, nxt=nxt):
            lanes, _, qptr, _ = c
            live = jnp.sum(lanes.phase != IDLE, dtype=jnp.int32)
            return (qptr < n) | (live > nxt)

        def body(c, block=block, block_fb=block_fb):
            lanes, out, qptr, count = c
            lanes, qptr = _refill(tr, lanes, queue, qptr)
            lanes = jax.lax.fori_loop(0, k_steps, lambda _, ln: _step(tr, ln, block, block_fb), lanes)
            lanes, out = _flush(tr, lanes, out)
            return lanes, out, qptr, count + 1

        lanes, out, qptr, count = jax.lax.while_loop(cond, body, (lanes, out, qptr, jnp.int32(0)))
        chunks.append(count)
    res = TraceResult(*(a[:n] for a in out))
    return res, WavefrontStats(chunks=jnp.stack(chunks), lanes=sizes, steps_per_chunk=k_steps)
