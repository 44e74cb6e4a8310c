"""A brute-force ray caster for tiny scenes laid out for XLA's CPU vectoriser (render's default there).

Same algorithm as :class:`~probeplace.geometry.BruteForceCaster` (Möller & Trumbore 1997, every ray
against every triangle), but written on structure-of-arrays components: rays as three (n,) arrays,
triangles as three (n_tri,) arrays per vector, so every operation is a plain (n, n_tri) broadcast that
XLA fuses into one loop. Two reasons to have it here:

* speed: no (n, n_tri, 3) intermediates and no 3-wide reductions; ~4–5 M closest-hit rays/s on two CPU
  cores for the Cornell box's 36 triangles;
* correctness: the vmapped (n, n_tri, 3) formulation of ``BruteForceCaster`` miscompiles on XLA:CPU
  (jaxlib 0.10.2) once a batch exceeds ~512 rays (``t`` comes out wrong for most rays, ``u, v`` stay
  right; see docs/render.md), which this layout does not trigger. The render tests check this caster
  against a float64 NumPy reference at batch sizes that trigger the bug.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from .._core import Hit, Scene
from ..geometry import AbstractRayCaster, complete_hit


class SmallSceneCaster(AbstractRayCaster):
    """Exact closest-hit / any-hit queries by testing every triangle; jittable (``jittable = True``).

    Quadratic in scene size: refused above ``MAX_TRIANGLES`` (use a BVH or Embree caster there).
    """

    scene: Scene
    v0: Float[Array, "3 n_tri"]
    e1: Float[Array, "3 n_tri"]
    e2: Float[Array, "3 n_tri"]

    MAX_TRIANGLES = 1024
    jittable = True

    def __init__(self, scene: Scene):
        if scene.n_triangles > self.MAX_TRIANGLES:
            raise ValueError(
                f"SmallSceneCaster is for tiny scenes (≤ {self.MAX_TRIANGLES} triangles); {scene.name!r} has "
                f"{scene.n_triangles}: pass a BVH or Embree caster (probeplace.geometry)"
            )
        tri = scene.vertices[scene.faces].astype(jnp.float32)
        self.scene = scene
        self.v0 = tri[:, 0].T
        self.e1 = (tri[:, 1] - tri[:, 0]).T
        self.e2 = (tri[:, 2] - tri[:, 0]).T

    def _intersect(self, origins, directions):
        """(t, u, v), each (n, n_tri); t = inf where the ray misses that triangle."""
        ox, oy, oz = (origins[:, i : i + 1] for i in range(3))
        dx, dy, dz = (directions[:, i : i + 1] for i in range(3))
        ax, ay, az = (self.e1[i][None] for i in range(3))
        bx, by, bz = (self.e2[i][None] for i in range(3))
        # Möller & Trumbore (1997): p = d × e2, det = e1 · p, s = o − v0, q = s × e1.
        px = dy * bz - dz * by
        py = dz * bx - dx * bz
        pz = dx * by - dy * bx
        det = ax * px + ay * py + az * pz
        ok = jnp.abs(det) > jnp.finfo(det.dtype).tiny * 1e6  # parallel ray: no hit, and no inf/NaN below
        inv = jnp.where(ok, 1.0 / jnp.where(ok, det, 1.0), 0.0)
        sx = ox - self.v0[0][None]
        sy = oy - self.v0[1][None]
        sz = oz - self.v0[2][None]
        u = (sx * px + sy * py + sz * pz) * inv
        qx = sy * az - sz * ay
        qy = sz * ax - sx * az
        qz = sx * ay - sy * ax
        v = (dx * qx + dy * qy + dz * qz) * inv
        t = (bx * qx + by * qy + bz * qz) * inv
        valid = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        return jnp.where(valid, t, jnp.inf), u, v

    @eqx.filter_jit
    def closest_hit(
        self,
        origins: Float[Array, "n_rays 3"],
        directions: Float[Array, "n_rays 3"],
        t_max: Float[Array, " n_rays"] | float = jnp.inf,
    ) -> Hit:
        t, u, v = self._intersect(origins, directions)
        t_max = jnp.broadcast_to(jnp.asarray(t_max, t.dtype), (t.shape[0],))
        t = jnp.where(t < t_max[:, None], t, jnp.inf)
        i = jnp.argmin(t, axis=1).astype(jnp.int32)
        pick = lambda a: jnp.take_along_axis(a, i[:, None], axis=1)[:, 0]
        t_hit = pick(t)
        tri = jnp.where(jnp.isfinite(t_hit), i, -1)
        return complete_hit(self.scene, t_hit, tri, jnp.stack([pick(u), pick(v)], axis=1))

    @eqx.filter_jit
    def occluded(
        self,
        origins: Float[Array, "n_rays 3"],
        directions: Float[Array, "n_rays 3"],
        t_max: Float[Array, " n_rays"] | float,
    ) -> Bool[Array, " n_rays"]:
        t, _, _ = self._intersect(origins, directions)
        t_max = jnp.broadcast_to(jnp.asarray(t_max, t.dtype), (t.shape[0],))
        return jnp.any(t < t_max[:, None], axis=1)
