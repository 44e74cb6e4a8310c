"""One interface for exact ray casting, whatever the backend.

Backends: Embree through embreex (host, CPU default), a pure-JAX BVH (jittable, runs on GPU), and a
pure-JAX brute-force caster for tiny scenes (the Cornell box's 36 triangles). All return the same
:class:`~probeplace._core.Hit`; :func:`complete_hit` derives normals and material from (t, tri, bary)
so every backend reports them identically.

Rays: ``origins`` and ``directions`` in the world frame; directions must be unit length, so ``t`` is a
distance in scene units. Hits with ``t <= t_min`` are ignored (``t_min`` defaults to 0; callers offset
secondary-ray origins themselves).
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from .._core import Hit, Scene, safe_normalize


class AbstractRayCaster(eqx.Module):
    """Closest-hit and any-hit queries for batches of rays against one scene's triangles."""

    @abc.abstractmethod
    def closest_hit(
        self,
        origins: Float[Array, "n_rays 3"],
        directions: Float[Array, "n_rays 3"],
        t_max: Float[Array, " n_rays"] | float = jnp.inf,
    ) -> Hit:
        """Nearest intersection with ``0 < t < t_max`` per ray (``tri = -1`` and ``t = inf`` on a miss)."""

    @abc.abstractmethod
    def occluded(
        self,
        origins: Float[Array, "n_rays 3"],
        directions: Float[Array, "n_rays 3"],
        t_max: Float[Array, " n_rays"] | float,
    ) -> Bool[Array, " n_rays"]:
        """True where any triangle is hit with ``0 < t < t_max`` (shadow rays)."""


def complete_hit(
    scene: Scene,
    t: Float[Array, " n_rays"],
    tri: Int[Array, " n_rays"],
    bary: Float[Array, "n_rays 2"],
) -> Hit:
    """Fill in geometric/shading normals and material for raw (t, tri, bary); misses get zeros / -1.

    The geometric normal is the front-face normal (counter-clockwise winding), *not* flipped toward the
    ray: shading code decides sidedness. The shading normal interpolates the crease-smoothed corner normals.
    """
    hit = tri >= 0
    safe_tri = jnp.where(hit, tri, 0)
    corners = scene.vertices[scene.faces[safe_tri]]  # (n, 3, 3)
    geo = safe_normalize(jnp.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]))
    u, v = bary[:, 0:1], bary[:, 1:2]
    cn = scene.corner_normals[safe_tri]
    shading = safe_normalize((1 - u - v) * cn[:, 0] + u * cn[:, 1] + v * cn[:, 2])
    zero = jnp.zeros_like(geo)
    return Hit(
        t=jnp.where(hit, t, jnp.inf),
        tri=jnp.where(hit, tri, -1).astype(jnp.int32),
        bary=jnp.where(hit[:, None], bary, 0.0),
        geo_normal=jnp.where(hit[:, None], geo, zero),
        shading_normal=jnp.where(hit[:, None], shading, zero),
        material=jnp.where(hit, scene.tri_material[safe_tri], -1).astype(jnp.int32),
    )


def intersect_triangles(
    origin: Float[Array, "3"],
    direction: Float[Array, "3"],
    v0: Float[Array, "n 3"],
    e1: Float[Array, "n 3"],
    e2: Float[Array, "n 3"],
) -> tuple[Float[Array, " n"], Float[Array, " n"], Float[Array, " n"]]:
    """Möller–Trumbore (1997) for one ray against n triangles given as v0 and edges e1 = v1−v0, e2 = v2−v0.

    Returns (t, u, v) with ``t = inf`` where the ray misses (parallel, outside, or behind). Branch-free,
    so it vectorises; the divisions are guarded so no NaN appears for parallel rays.
    """
    direction = jnp.broadcast_to(direction, e2.shape)  # explicit: tests run with strict rank promotion
    p = jnp.cross(direction, e2)
    det = jnp.sum(e1 * p, axis=-1)
    ok = jnp.abs(det) > jnp.finfo(det.dtype).tiny * 1e6
    inv = jnp.where(ok, 1.0 / jnp.where(ok, det, 1.0), 0.0)
    s = origin[None, :] - v0
    u = jnp.sum(s * p, axis=-1) * inv
    q = jnp.cross(s, e1)
    v = jnp.sum(direction * q, axis=-1) * inv
    t = jnp.sum(e2 * q, axis=-1) * inv
    valid = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    return jnp.where(valid, t, jnp.inf), u, v


class BruteForceCaster(AbstractRayCaster):
    """Every ray against every triangle, in JAX. The fastest exact choice for tiny scenes (tens of
    triangles: no traversal overhead, perfectly vectorised); quadratic, so refuse large scenes."""

    scene: Scene
    v0: Float[Array, "n_tri 3"]
    e1: Float[Array, "n_tri 3"]
    e2: Float[Array, "n_tri 3"]
    chunk: int = eqx.field(static=True, default=16384)

    MAX_TRIANGLES = 4096

    def __init__(self, scene: Scene, chunk: int = 16384):
        if scene.n_triangles > self.MAX_TRIANGLES:
            raise ValueError(
                f"BruteForceCaster is for tiny scenes (≤ {self.MAX_TRIANGLES} triangles); "
                f"{scene.name!r} has {scene.n_triangles}: use the 'bvh' or 'embree' backend"
            )
        tri = scene.vertices[scene.faces]
        self.scene = scene
        self.v0 = tri[:, 0]
        self.e1 = tri[:, 1] - tri[:, 0]
        self.e2 = tri[:, 2] - tri[:, 0]
        self.chunk = chunk

    def _one(self, origin, direction, t_max):
        t, u, v = intersect_triangles(origin, direction, self.v0, self.e1, self.e2)
        t = jnp.where(t < t_max, t, jnp.inf)
        i = jnp.argmin(t)
        return t[i], jnp.where(jnp.isfinite(t[i]), i, -1).astype(jnp.int32), jnp.stack([u[i], v[i]])

    @eqx.filter_jit
    def closest_hit(self, origins, directions, t_max=jnp.inf):
        n = origins.shape[0]
        t_max = jnp.broadcast_to(jnp.asarray(t_max, origins.dtype), (n,))
        t, tri, bary = jax.lax.map(
            lambda a: self._one(*a), (origins, directions, t_max), batch_size=min(self.chunk, max(n, 1))
        )
        return complete_hit(self.scene, t, tri, bary)

    @eqx.filter_jit
    def occluded(self, origins, directions, t_max):
        n = origins.shape[0]
        t_max = jnp.broadcast_to(jnp.asarray(t_max, origins.dtype), (n,))

        def one(a):
            o, d, tm = a
            t, _, _ = intersect_triangles(o, d, self.v0, self.e1, self.e2)
            return jnp.any(t < tm)

        return jax.lax.map(one, (origins, directions, t_max), batch_size=min(self.chunk, max(n, 1)))
