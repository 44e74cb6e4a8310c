"""Whether points are seen by the light-field tracer's probes (issue 33: the unresolved share among rays
whose origin some usable probe sees).

A point x is *seen* when one of the K nearest usable probes of x's voxel — the pool the tracer's fallback
search draws from (``LightFieldTracer.near``, :func:`~probeplace.probes.nearest_index`: the
``_FALLBACK_POOL`` = 32 usable probes nearest the voxel's centre among those within ``fallback_radius``
probe spacings plus half the voxel's diagonal) — sees it by the tracer's own test at one point
(``_trace._sees``: x lies in front of the surfel of the probe's march cell in x's direction, of every
candidate surfel where the cell is ambiguous and of a concave crease's partner, by ``fallback_margin`` of
the surfel's distance). Unlike the fallback search itself, the pool is not cut to ``fallback_radius``
spacings of x: a probe of the pool that sees x counts however far it is. A ray whose origin no probe of
the pool sees can only be resolved by luck; one whose origin is seen and still ends unresolved is the
tracer's (or the probes' resolution's) doing.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from ._trace import LightFieldTracer, _sees


def _seen_one(tr: LightFieldTracer, x: Float[Array, "3"]) -> Bool[Array, ""]:
    """Whether some probe of x's pool (``tr.near.lookup``; -1 padded, usable probes only) sees ONE point x."""
    pool, _ = tr.near.lookup(x)
    return jnp.any(_sees(tr, pool, x))


@eqx.filter_jit
def origins_seen(
    tr: LightFieldTracer, points: Float[Array, "n_points 3"], *, chunk: int = 4096
) -> Bool[Array, " n_points"]:
    """Whether each point is seen by one of the K nearest usable probes (module docstring).

    Args:
        tr: from :func:`make_tracer`.
        points: world-frame points, e.g. the origins of secondary rays (a surface point offset along its
            normal, as the tracer is given them: a point exactly on a surface lies on the threshold of
            the test).
        chunk: points tested at a time (``lax.map``): bounds the working memory (static: one compile per
            value).

    Returns:
        A bool per point (jitted; one compile per tracer layout, point count and ``chunk``).
    """
    pts = jnp.asarray(points, tr.pos_world.dtype)
    if pts.shape[0] == 0:
        return jnp.zeros((0,), bool)
    return jax.lax.map(lambda x: _seen_one(tr, x), pts, batch_size=min(chunk, pts.shape[0]))
