"""The wavefront lane scheduler, once for the three loops that march many rays in a fixed set of lanes:
the BVH traversal (``geometry._bvh_traverse``), the SDF sphere tracer (``geometry._sphere_trace``) and the
light-field tracer (``probes.tracer._wavefront``). ``w`` lanes advance together; every few steps the lanes
whose ray finished write its result and take the next rays of the queue, so a few long rays do not hold a
whole batch (issue 35: the three loops each wrote this bookkeeping their own way).

A lane holds a ray id, or −1 when idle; the queue is the ray ids ``0 … n − 1`` in order, its head ``next``
the first not yet handed out. Only integer bookkeeping happens here: which lane traces which ray never
changes a ray's result.
"""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array, Bool, Int


def take_queued(
    free: Bool[Array, " w"], head: Int[Array, ""], n: int
) -> tuple[Int[Array, " w"], Bool[Array, " w"], Int[Array, ""]]:
    """Hand the free lanes, in lane order, the next rays of a queue of ``n`` whose head is ``head``.

    Returns:
        (ray, take, head): each lane's new ray id (−1 where the lane is free and the queue is empty; the
        lane's own value is for the caller to keep where the lane is not free), which free lanes took a
        ray, and the queue's new head.
    """
    new = head + jnp.cumsum(free, dtype=jnp.int32) - 1
    take = free & (new < n)
    return jnp.where(take, new, -1), take, head + jnp.sum(take, dtype=jnp.int32)


def write_finished(
    out: tuple[Array, ...], done: Bool[Array, " w"], ray: Int[Array, " w"], values: tuple, n: int
):
    """``out`` (arrays with a row per ray) with the rows of the rays of the ``done`` lanes set to
    ``values`` (one per array, a row per lane); the other lanes write to row ``n``, dropped when the
    arrays have ``n`` rows (a sink row when they have ``n + 1``)."""
    rows = jnp.where(done, ray, n)
    return tuple(a.at[rows].set(v.astype(a.dtype), mode="drop") for a, v in zip(out, values, strict=True))
