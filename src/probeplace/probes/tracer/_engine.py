"""The engine switch above the two light-field tracers: :func:`trace_light_field` runs a batch of rays on
the engine ``TraceConfig.engine`` names — the per-ray engine (``_trace.trace_ray``, vmapped) or the
wavefront state machine (``_wavefront.trace_wavefront``). Neither engine imports the other; both must give
the same answers (``tests/probes/test_wavefront.py``)."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._trace import LightFieldTracer, TraceResult, trace_ray
from ._wavefront import trace_wavefront


@eqx.filter_jit
def trace_light_field(
    tr: LightFieldTracer,
    origins: Float[Array, "n_rays 3"],
    directions: Float[Array, "n_rays 3"],
    t_max: Float[Array, " n_rays"] | None = None,
    *,
    chunk: int | None = None,
) -> TraceResult:
    """Trace a batch of rays through the light-field probes (jitted; one compile per tracer layout).

    Args:
        tr: from :func:`make_tracer`.
        origins: ray origins, world frame (offset secondary rays off their surface yourself).
        directions: unit directions.
        t_max: optional per-ray maximum distance (default: the scene diagonal).
        chunk: per-ray engine: trace this many rays at a time (``lax.map``), so working memory stays
            bounded as the batch grows; ``None`` traces all rays at once (static: one compile per value).
            The wavefront engine ignores it (its working memory is ``wavefront_lanes`` lanes).

    Returns:
        A :class:`TraceResult`; unresolved rays are flagged, never counted as hits or misses. Both
        engines (``tr.config.engine``) return the same result.
    """
    dt = tr.pos_world.dtype
    origins = jnp.asarray(origins, dt)
    directions = jnp.asarray(directions, dt)
    if t_max is None:
        t_max = jnp.full(origins.shape[:1], jnp.inf, dt)
    t_max = jnp.asarray(t_max, dt)
    if tr.config.engine == "wavefront":
        return trace_wavefront(tr, origins, directions, t_max)[0]
    if chunk is None:
        out = jax.vmap(trace_ray, in_axes=(None, 0, 0, 0))(tr, origins, directions, t_max)
    else:
        out = jax.lax.map(lambda x: trace_ray(tr, *x), (origins, directions, t_max), batch_size=chunk)
    return TraceResult(*out)
