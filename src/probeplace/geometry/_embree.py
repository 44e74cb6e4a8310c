"""Embree (through embreex) behind :class:`AbstractRayCaster`: the exact CPU reference and CPU default.

Host code: queries go numpy → Embree → numpy, so :class:`EmbreeCaster` is *not* jittable, differentiable
or vmappable (call it outside ``jax.jit``; use :class:`~probeplace.geometry.BVHCaster` inside). embreex's
``run`` casts one ray after another on the calling thread; ``threads > 1`` splits a batch into chunks cast
from a thread pool (embreex releases the GIL while it casts: measured 1.5× on 2 cores). Coherent rays
(``closest_hit_map(..., coherent=True)``: the geometry bake's) go in Embree's 16-ray packets where they
are available (``_embree_packets``).
"""

from __future__ import annotations

import itertools
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from .._core import Hit, ProbeplaceError, Scene
from ._embree_packets import W as _PACKET
from ._embree_packets import packet_scene
from ._raycast import AbstractRayCaster, complete_hit, face_normals


class EmbreeUnavailableError(ProbeplaceError, ImportError):
    """embreex (Embree's Python binding) could not be imported."""


def _import_embree():
    try:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh
    except ImportError as e:  # pragma: no cover - depends on the install
        raise EmbreeUnavailableError(
            f"the 'embree' ray-casting backend needs the embreex package ({e}); install it "
            "(`pip install embreex`, x86-64/arm64 wheels) or use backend='bvh'"
        ) from e
    return rtcore_scene, TriangleMesh


class _EmbreeHandle:
    """Owns the embreex scene; compared and hashed by identity (an equinox static field)."""

    def __init__(self, triangles: np.ndarray):
        rtcore_scene, TriangleMesh = _import_embree()
        self.triangles = np.ascontiguousarray(triangles, np.float32)
        self.scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self.scene, self.triangles)
        # embreex commits (builds its BVH) on the first query: do it now so query timings are queries
        self.scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), output=1)
        self._packets_lock = threading.Lock()
        self._packets: list = []  # [PacketScene or None], built on the first coherent query

    def packets(self):
        """The scene for Embree's packets (``_embree_packets``), built once on first use; ``None`` where
        they are unavailable."""
        with self._packets_lock:
            if not self._packets:
                self._packets.append(packet_scene(self.triangles))
            return self._packets[0]


def _chunks(n: int, threads: int, step: int = 1) -> list[slice]:
    """Slices of a batch of ``n`` rays for ``threads`` threads: several a thread (up to 8, each of at least
    ~16 k rays), taken in turn, so a thread whose rays were cheap (a probe inside a wall) takes more,
    instead of waiting for the other's half (5 % of the 512² bake's casts, 2 threads); one slice for a
    tiny batch (no point in threads). Slices start at multiples of ``step`` (a packet's rays stay
    together, whatever the thread count)."""
    k = 1 if threads == 1 else max(1, min(8 * threads, n // 16384 + 1))
    edges = (np.linspace(0, n, k + 1) // step * step).astype(int)
    edges[-1] = n
    return [slice(a, b) for a, b in itertools.pairwise(edges)]


class EmbreeCaster(AbstractRayCaster):
    """Exact closest-hit / any-hit queries with Intel Embree (host, float32 inside).

    Not jittable (see the module docstring). Hits with ``t <= 0`` and ``t >= t_max`` are ignored, as for
    every caster (Embree itself accepts ``tnear <= t <= tfar``; ``tfar`` is set to the float below
    ``t_max``). Results are returned in the dtype of ``origins``.

    Args:
        scene: the scene.
        threads: host threads per query; ``None`` uses every core (``os.cpu_count()``), 1 is Embree on one
            thread (the benchmark's reference).

    Raises:
        EmbreeUnavailableError: embreex is not installed.
    """

    jittable: ClassVar[bool] = False  # numpy → Embree → numpy: concrete arrays only

    scene: Scene
    tri_normal: Float[Array, "n_tri 3"]  # the scene's face_normals, for complete_hit
    handle: _EmbreeHandle = eqx.field(static=True)
    threads: int = eqx.field(static=True)

    def __init__(self, scene: Scene, *, threads: int | None = None):
        if threads is not None and threads < 1:
            raise ValueError(f"threads must be >= 1 or None, got {threads}")
        tri = np.asarray(scene.vertices, np.float32)[np.asarray(scene.faces)]
        self.scene = scene
        self.tri_normal = face_normals(tri)
        self.handle = _EmbreeHandle(tri)
        self.threads = int(threads or os.cpu_count() or 1)

    def _run(self, origins, directions, t_max, query, coherent=False):
        o = np.ascontiguousarray(np.asarray(origins), np.float32)
        d = np.ascontiguousarray(np.asarray(directions), np.float32)
        if o.ndim != 2 or o.shape[1] != 3 or d.shape != o.shape:
            raise ValueError(f"origins and directions must both be (n_rays, 3), got {o.shape} and {d.shape}")
        n = o.shape[0]
        tm = np.broadcast_to(np.asarray(t_max, np.float32), (n,))
        # embreex writes the hit distance into this array in place: always hand it a fresh one
        tfar = np.nextafter(tm, np.float32(-np.inf)).astype(np.float32)
        tfar = np.where(tm > 0, tfar, np.float32(0))

        packets = self.handle.packets() if coherent and query == "INTERSECT" else None

        def one(sl):
            if packets is not None:
                return packets.intersect(o[sl], d[sl], tfar[sl])
            if query == "OCCLUDED":
                return self.handle.scene.run(o[sl], d[sl], dists=tfar[sl].copy(), query="OCCLUDED")
            return self.handle.scene.run(o[sl], d[sl], dists=tfar[sl].copy(), output=1)

        parts = _chunks(n, self.threads, _PACKET if packets else 1)
        if len(parts) == 1:
            res = [one(parts[0])]
        else:
            with ThreadPoolExecutor(min(self.threads, len(parts))) as pool:
                res = list(pool.map(one, parts))
        if query == "OCCLUDED":
            return np.concatenate(res) if res else np.zeros(0, np.int32)
        return {k: np.concatenate([r[k] for r in res]) for k in ("tfar", "primID", "u", "v")}

    def host_closest_hit(self, origins: np.ndarray, directions: np.ndarray, t_max=np.inf):
        """:meth:`closest_hit` on the host, NumPy in and out, with no JAX op (for checks that run before
        anything compiles): (t float64, ``inf`` on a miss; triangle int64, -1 on a miss)."""
        r = self._run(origins, directions, t_max, "INTERSECT")
        tri = np.asarray(r["primID"], np.int64)
        tri = np.where(tri >= 0, tri, -1)
        return np.where(tri >= 0, np.asarray(r["tfar"], np.float64), np.inf), tri

    def closest_hit(
        self,
        origins: Float[Array, "n_rays 3"],
        directions: Float[Array, "n_rays 3"],
        t_max: Float[Array, " n_rays"] | float = jnp.inf,
    ) -> Hit:
        """Nearest intersection with ``0 < t < t_max`` per ray (``tri = -1`` and ``t = inf`` on a miss)."""
        return self.closest_hit_map(_the_hit, origins, directions, t_max=t_max)

    def closest_hit_map(self, fn, origins, directions, *args, t_max=jnp.inf, coherent=False):
        """``fn(hit, *args)`` (:meth:`AbstractRayCaster.closest_hit_map`): Embree's raw answers go into one
        compiled program that completes the hit and applies ``fn``. ``coherent``: cast in Embree's 16-ray
        packets (``_embree_packets``) where they are available."""
        # the rays' dtype without a device copy of them (the bake hands over 2 M host rays a batch)
        dtype = jax.dtypes.canonicalize_dtype(
            origins.dtype if hasattr(origins, "dtype") else np.asarray(origins).dtype
        )
        r = self._run(origins, directions, t_max, "INTERSECT", coherent)
        raw = (r["tfar"], r["primID"], r["u"], r["v"])
        return _complete_map(fn, self.scene, self.tri_normal, *raw, dtype, *args)

    def occluded(
        self,
        origins: Float[Array, "n_rays 3"],
        directions: Float[Array, "n_rays 3"],
        t_max: Float[Array, " n_rays"] | float,
    ) -> Bool[Array, " n_rays"]:
        """True where any triangle is hit with ``0 < t < t_max`` (shadow rays)."""
        return jnp.asarray(self.occluded_host(origins, directions, t_max))

    def occluded_host(self, origins, directions, t_max) -> np.ndarray:
        """:meth:`occluded` as a host (NumPy) boolean array: no device round trip for host callers."""
        ids = self._run(origins, directions, t_max, "OCCLUDED")
        return np.asarray(ids != -1)


def _the_hit(hit: Hit) -> Hit:
    """:meth:`EmbreeCaster.closest_hit`'s ``fn``: the completed hit itself."""
    return hit


@eqx.filter_jit
def _complete_map(fn, scene: Scene, tri_normal, tfar, prim, u, v, dtype, *args):
    """``fn(hit, *args)`` of the hit Embree answered (``tfar``, ``primID``, ``u``, ``v``; ``primID`` −1 on
    a miss) in the rays' ``dtype``: one program (``complete_hit``, then ``fn``)."""
    hit = prim >= 0
    bary = jnp.where(hit[:, None], jnp.stack([u, v], axis=1), 0.0).astype(dtype)
    t = jnp.where(hit, tfar, jnp.inf).astype(dtype)
    tri = jnp.where(hit, prim, -1).astype(jnp.int32)
    return fn(complete_hit(scene, t, tri, bary, tri_normal), *args)
