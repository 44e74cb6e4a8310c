"""One interface for exact ray casting, whatever the backend.

Backends: Embree through embreex (host, CPU default), a pure-JAX BVH (jittable, runs on GPU), and a
pure-JAX brute-force caster for tiny scenes (the Cornell box's 36 triangles). All return the same
:class:`~probeplace._core.Hit`; :func:`complete_hit` derives normals and material from (t, tri, bary)
so every backend reports them identically.

Rays: ``origins`` and ``directions`` in the world frame; directions must be unit length, so ``t`` is a
distance in scene units. Hits with ``t <= t_min`` are ignored (``t_min`` defaults to 0; callers offset
secondary-ray origins themselves).
"""

# No ``from __future__ import annotations`` here: equinox cannot read a stringified AbstractClassVar.
import abc
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from .._core import Hit, Scene, padded_count, safe_normalize


class AbstractRayCaster(eqx.Module):
    """Closest-hit and any-hit queries for batches of rays against one scene's triangles.

    Every caster states what it can do, so callers read it instead of guessing from the type:

    * ``jittable`` (class attribute): whether its queries can be traced inside ``jax.jit``/``vmap`` (the
      JAX casters) or must be called from the host with concrete arrays (Embree). The path tracer runs
      its whole bounce loop in one jitted function for a jittable caster and a host loop otherwise.
    * :meth:`occluded_host`: the any-hit query from and to host (NumPy) arrays, for host-driven callers
      such as the placement's binary visibility; Embree answers it without a device round trip.
    """

    jittable: eqx.AbstractClassVar[bool]

    @abc.abstractmethod
    def closest_hit(
        self,
        origins: Float[Array, "n_rays 3"],
        directions: Float[Array, "n_rays 3"],
        t_max: Float[Array, " n_rays"] | float = jnp.inf,
    ) -> Hit:
        """Nearest intersection with ``0 < t < t_max`` per ray (``tri = -1`` and ``t = inf`` on a miss)."""

    def closest_hit_map(self, fn, origins, directions, *args, t_max=jnp.inf, coherent=False):
        """``fn(hit, *args)`` of :meth:`closest_hit`'s ``hit``, in one compiled program with the hit's
        completion where the caster can (a host caster: Embree; a jittable one runs it under the caller's
        jit as it is). ``fn`` is a module-level function (compiled programs are kept per function): the
        bake reduces 2 M hits a batch to what its maps store, and the hit's unused fields (material,
        barycentrics) are never written (issue 33). ``coherent``: the caller's hint that each 16
        consecutive rays are coherent (one origin, a 4×4 tile of directions); a caster that traces packets
        uses it (Embree), the others ignore it."""
        return _closest_hit_map(self, fn, origins, directions, t_max, *args)

    @abc.abstractmethod
    def occluded(
        self,
        origins: Float[Array, "n_rays 3"],
        directions: Float[Array, "n_rays 3"],
        t_max: Float[Array, " n_rays"] | float,
    ) -> Bool[Array, " n_rays"]:
        """True where any triangle is hit with ``0 < t < t_max`` (shadow rays)."""

    @abc.abstractmethod
    def occluded_host(self, origins, directions, t_max) -> np.ndarray:
        """:meth:`occluded` for host callers: NumPy (or any array) inputs, a NumPy boolean array out."""


class AbstractJaxRayCaster(AbstractRayCaster):
    """A caster whose queries are JAX code: jittable, and its host query is the jitted one converted.

    Each new batch size compiles :meth:`occluded` once more, so :meth:`occluded_host` pads its batch to
    a few sizes (:func:`_host_batch_size`): host callers whose batches vary (the bake's inside test, the
    fitness's camera test) compile a few programs a process, not one a call.
    """

    jittable: ClassVar[bool] = True

    def occluded_host(self, origins, directions, t_max) -> np.ndarray:
        """:meth:`occluded` as a host (NumPy) boolean array, computed by the jitted query on a padded batch.

        The padding rays have ``t_max = 0``, so they hit nothing (a hit needs ``0 < t < t_max``); they are
        cut off before returning.
        """
        origins = np.asarray(origins)  # once: a device array is fetched here, not again below
        dtype = jax.dtypes.canonicalize_dtype(origins.dtype)
        n = len(origins)
        size = _host_batch_size(n)
        o = np.zeros((size, 3), dtype)
        d = np.zeros((size, 3), dtype)
        tm = np.zeros(size, dtype)
        o[:n], d[:n], tm[:n] = origins, directions, t_max
        d[n:, 2] = 1.0  # unit directions where a caster reads them
        return np.asarray(self.occluded(jnp.asarray(o), jnp.asarray(d), jnp.asarray(tm)))[:n]


def _host_batch_size(n: int) -> int:
    """The padded size of a host batch of ``n`` rays: a power of two from 64 up to 65,536, then multiples
    of 65,536 (at most twice the rays, or 65,535 more)."""
    return padded_count(n, lo=64, step=65536)


@eqx.filter_jit
def _closest_hit_map(caster: AbstractRayCaster, fn, origins, directions, t_max, *args):
    """:meth:`AbstractRayCaster.closest_hit_map` of a jittable caster: the query and ``fn`` in one program."""
    return fn(caster.closest_hit(origins, directions, t_max), *args)


@jax.jit  # one program per triangle count: eagerly, a caster's table cost ~0.5 s of small compiles a scene
def face_normals(corners: Float[Array, "n 3 3"]) -> Float[Array, "n 3"]:
    """Unit front-face normals of triangles given by their corners (counter-clockwise seen from the front)."""
    return safe_normalize(jnp.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]))


# One compiled program (per ray count): a host caster (Embree) calls it eagerly on millions of rays, where
# its fifteen jnp operations were fifteen programs and as many passes over memory (issue 33).
@eqx.filter_jit
def complete_hit(
    scene: Scene,
    t: Float[Array, " n_rays"],
    tri: Int[Array, " n_rays"],
    bary: Float[Array, "n_rays 2"],
    tri_normal: Float[Array, "n_tri 3"] | None = None,
) -> Hit:
    """Fill in geometric/shading normals and material for raw (t, tri, bary); misses get zeros / -1.

    The geometric normal is the front-face normal (counter-clockwise winding), *not* flipped toward the
    ray: shading code decides sidedness. The shading normal interpolates the crease-smoothed corner normals.
    ``tri_normal``: the scene's :func:`face_normals`, computed once by a caster that completes millions of
    hits (one gather a hit instead of four: a third of the bake's geometry program, issue 33).
    """
    hit = tri >= 0
    safe_tri = jnp.where(hit, tri, 0)
    if tri_normal is None:
        geo = face_normals(scene.vertices[scene.faces[safe_tri]])  # corners (n, 3, 3)
    else:
        geo = tri_normal[safe_tri]
    cn = scene.corner_normals[safe_tri]
    u, v = bary[:, 0:1].astype(cn.dtype), bary[:, 1:2].astype(cn.dtype)
    shading = safe_normalize((1 - u - v) * cn[:, 0] + u * cn[:, 1] + v * cn[:, 2])
    # normals come out in the rays' dtype (t's), whatever the scene's float width
    geo, shading = geo.astype(t.dtype), shading.astype(t.dtype)
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


class BruteForceCaster(AbstractJaxRayCaster):
    """Every ray against every triangle, in JAX. The fastest exact choice for tiny scenes (tens of
    triangles: no traversal overhead, perfectly vectorised); quadratic, so refuse large scenes.

    Layout: rays as (n,) component arrays, and a running closest hit updated one triangle at a time
    (a ``fori_loop`` over the triangles, 4 per iteration), each test a ray–plane distance plus two
    precomputed barycentric planes (cheaper than Möller–Trumbore; see ``__init__``). The earlier vmapped
    (n, n_tri, 3) formulation was ~6x slower on CPU and miscompiled on XLA:CPU for batches over ~512 rays
    (see docs/render.md, "Known issue"). Values are computed in the rays' dtype.
    Ties (coplanar overlapping triangles at the same distance) go to the lower triangle id.
    """

    scene: Scene
    planes: Float[Array, "12 n_tri"]
    chunk: int = eqx.field(static=True, default=65536)

    MAX_TRIANGLES = 4096
    UNROLL = 4  # triangles per fori_loop iteration
    UNROLL_MAX = 0  # full unrolling compiles for ~15 s (36 triangles) and was not faster

    def __init__(self, scene: Scene, chunk: int = 65536):
        if scene.n_triangles > self.MAX_TRIANGLES:
            raise ValueError(
                f"BruteForceCaster is for tiny scenes (≤ {self.MAX_TRIANGLES} triangles); "
                f"{scene.name!r} has {scene.n_triangles}: use the 'bvh' or 'embree' backend"
            )
        if chunk < 1:
            raise ValueError(f"chunk must be >= 1, got {chunk}")
        # Per triangle, in float64 on the host: v0, the (unnormalised) normal n = e1 × e2 and the two
        # "barycentric planes" A = (e2 × n)/|n|², B = (n × e1)/|n|², for which (p − v0)·A = u and
        # (p − v0)·B = v for any point p = v0 + u·e1 + v·e2 of the triangle's plane (Baldwin & Weber
        # 2016, "Fast ray-triangle intersections by coordinate transformation", JCGT 5(3), precompute
        # the same affine map). Degenerate triangles get NaN planes and are never hit.
        tri = np.asarray(scene.vertices, np.float64)[np.asarray(scene.faces)]
        v0 = tri[:, 0]
        e1, e2 = tri[:, 1] - v0, tri[:, 2] - v0
        n = np.cross(e1, e2)
        with np.errstate(divide="ignore", invalid="ignore"):
            nn = np.sum(n * n, axis=1, keepdims=True)
            a, b = np.cross(e2, n) / nn, np.cross(n, e1) / nn
        self.scene = scene
        self.planes = jnp.asarray(np.concatenate([v0, n, a, b], axis=1).T, scene.vertices.dtype)
        self.chunk = chunk

    def _scan(self, o, d, t_max, any_hit):
        """Closest (t, tri, u, v) for rays given as component tuples o = (ox, oy, oz), d, each (m,)."""
        dtype = o[0].dtype
        pl = self.planes.astype(dtype)
        n_tri = pl.shape[1]

        def update(i, best):
            tb, tr, bu, bv = best
            # s = v0 − o; t = (s·n)/(d·n) (ray–plane); w = p − v0 = t·d − s; u = w·A, v = w·B. About 18
            # multiply-adds and a division per pair, against 27 for Möller–Trumbore (1.9x measured here).
            sx, sy, sz = pl[0, i] - o[0], pl[1, i] - o[1], pl[2, i] - o[2]
            den = d[0] * pl[3, i] + d[1] * pl[4, i] + d[2] * pl[5, i]
            t = (sx * pl[3, i] + sy * pl[4, i] + sz * pl[5, i]) / den  # den = 0: inf/NaN, never accepted
            wx, wy, wz = t * d[0] - sx, t * d[1] - sy, t * d[2] - sz
            u = wx * pl[6, i] + wy * pl[7, i] + wz * pl[8, i]
            v = wx * pl[9, i] + wy * pl[10, i] + wz * pl[11, i]
            better = (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & (t < tb)
            return (
                jnp.where(better, t, tb),
                jnp.where(better, jnp.asarray(i, jnp.int32), tr),
                jnp.where(better, u, bu),
                jnp.where(better, v, bv),
            )

        z = jnp.zeros_like(o[0])
        best = (t_max, jnp.full(z.shape, -1, jnp.int32), z, z)
        if n_tri <= self.UNROLL_MAX:
            for i in range(n_tri):
                best = update(i, best)
        else:
            best = jax.lax.fori_loop(0, n_tri, update, best, unroll=self.UNROLL)
        tb, tr, bu, bv = best
        return jnp.where(tr >= 0, tb, jnp.inf), tr, bu, bv

    def _trace(self, origins, directions, t_max, any_hit=False):
        if origins.ndim != 2 or origins.shape[-1] != 3 or directions.shape != origins.shape:
            raise ValueError(
                f"origins and directions must both be (n_rays, 3), got {origins.shape} and {directions.shape}"
            )
        n = origins.shape[0]
        dtype = origins.dtype
        t_max = jnp.broadcast_to(jnp.asarray(t_max, dtype), (n,))
        c = max(1, min(self.chunk, n))
        pad = (-n) % c
        o = jnp.pad(origins, ((0, pad), (0, 0))).T.reshape(3, -1, c)
        d = jnp.pad(directions.astype(dtype), ((0, pad), (0, 0))).T.reshape(3, -1, c)
        tm = jnp.pad(t_max, (0, pad)).reshape(-1, c)
        out = jax.lax.map(
            lambda a: self._scan(tuple(a[0]), tuple(a[1]), a[2], any_hit),
            (o.swapaxes(0, 1), d.swapaxes(0, 1), tm),
        )
        return tuple(x.reshape(-1)[:n] for x in out)

    @eqx.filter_jit
    def closest_hit(self, origins, directions, t_max=jnp.inf):
        t, tri, u, v = self._trace(origins, directions, t_max)
        return complete_hit(self.scene, t, tri, jnp.stack([u, v], axis=1))

    @eqx.filter_jit
    def occluded(self, origins, directions, t_max):
        _, tri, _, _ = self._trace(origins, directions, t_max, any_hit=True)
        return tri >= 0
