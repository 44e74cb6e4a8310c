"""Test helpers for ray casting: random rays, and a float64 NumPy check of hits against a reference.

Two casters may legitimately report different triangles for one ray when overlapping coplanar triangles
are hit at the same distance (the Cornell box's short block stands on the floor with its bottom face;
the temple and Sponza have overlapping coplanar quads). Which of the tied triangles a caster reports
depends on its traversal order, and Embree's traversal order depends on the CPU instruction set it
picks at run time (BVH4 on SSE, BVH8 on AVX2/AVX-512), so the *share* of identical triangle ids is
machine-dependent and decides nothing here. What is judged, per ray: the same hit or miss, the same
distance, and the same triangle or else a verified tie — the float64 Möller–Trumbore test confirms that
the ray crosses *both* triangles at the same distance. The same-id share is only reported.

:func:`compare_hits` is NumPy only and also computes ``benchmarks/raycast.py``'s agreement keys.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

#: Relative float64 slack of a verified tie (of max(1, t)): generous for float32 vertex data, and far
#: below any distance between two distinct surfaces a ray crosses.
TIE_RTOL = 1e-4
#: float32 distances from two different intersection formulas: a few ulp of the scene extent apart.
T_RTOL = 1e-5


def random_rays(scene, n: int, *, seed: int):
    """Origins uniform in the scene's box (shrunk by 5 %), directions uniform on the sphere; float32."""
    rng = np.random.default_rng(seed)
    v = np.asarray(scene.vertices, np.float64)
    lo, hi = v.min(0), v.max(0)
    pad = 0.05 * (hi - lo)
    o = rng.uniform(lo + pad, hi - pad, (n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32)


def ray_triangle_t(tri: np.ndarray, o: np.ndarray, d: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """float64 Möller–Trumbore distance of ray i to triangle i ((n,3,3), (n,3), (n,3)); inf on a miss.

    ``eps`` widens the barycentric bounds a little, so a hit on a shared edge counts for both triangles.
    """
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    p = np.cross(d, e2)
    det = np.sum(e1 * p, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = o - tri[:, 0]
        u = np.sum(s * p, axis=1) * inv
        q = np.cross(s, e1)
        v = np.sum(d * q, axis=1) * inv
        t = np.sum(e2 * q, axis=1) * inv
    ok = (u >= -eps) & (v >= -eps) & (u + v <= 1 + eps) & (t > 0)
    return np.where(ok, t, np.inf)


def verified_ties(tris, o, d, tri_a, tri_b, *, rtol: float = TIE_RTOL) -> np.ndarray:
    """Per ray: both hit, *different* triangles, and in float64 the ray crosses both at the same distance.

    Args:
        tris: (n_tri, 3, 3) triangle corners of the scene.
        o, d: (n, 3) rays.
        tri_a, tri_b: (n,) triangle ids (-1: miss).
    """
    tri_a, tri_b = np.asarray(tri_a), np.asarray(tri_b)
    both = (tri_a >= 0) & (tri_b >= 0) & (tri_a != tri_b)
    tie = np.zeros(tri_a.shape, bool)
    if both.any():
        tris = np.asarray(tris, np.float64)
        oo, dd = np.asarray(o, np.float64)[both], np.asarray(d, np.float64)[both]
        ta = ray_triangle_t(tris[tri_a[both]], oo, dd)
        tb = ray_triangle_t(tris[tri_b[both]], oo, dd)
        # both must be crossed (finite): with ta = inf the scale below would accept any tb
        crossed = np.isfinite(ta) & np.isfinite(tb)
        with np.errstate(invalid="ignore"):
            tie[both] = crossed & (np.abs(ta - tb) <= rtol * np.maximum(1.0, np.abs(ta)))
    return tie


def tie_or_same(scene, o, d, tri_a, tri_b, *, rtol: float = TIE_RTOL):
    """Per ray: (same triangle or both miss, that or a verified coplanar tie); see the module docstring."""
    tri_a, tri_b = np.asarray(tri_a), np.asarray(tri_b)
    same = tri_a == tri_b
    tris = np.asarray(scene.vertices, np.float64)[np.asarray(scene.faces)]
    return same, same | verified_ties(tris, o, d, tri_a, tri_b, rtol=rtol)


class HitComparison(NamedTuple):
    """Per-ray masks of :func:`compare_hits`; ``agree`` is the verdict, the rest explain it."""

    same_hit: np.ndarray  # both hit or both miss
    same_id: np.ndarray  # the same triangle id (or both miss)
    tie: np.ndarray  # different triangles, both crossed at the same distance (float64)
    same_t: np.ndarray  # both miss, or both hit within T_RTOL of the distance and of the scene extent

    @property
    def agree(self) -> np.ndarray:
        return self.same_hit & self.same_t & (self.same_id | self.tie)

    @property
    def agreement(self) -> float:
        """Share of rays that agree: machine-independent (1.0 for two correct casters)."""
        return float(self.agree.mean()) if self.agree.size else 1.0

    @property
    def same_id_share(self) -> float:
        """Share of rays with the very same triangle id: depends on traversal order (report only)."""
        return float(self.same_id.mean()) if self.same_id.size else 1.0


def compare_hits(tris, o, d, tri, t, tri_ref, t_ref, *, rtol_t: float = T_RTOL) -> HitComparison:
    """Judge hits ``(tri, t)`` against a reference ``(tri_ref, t_ref)`` per ray (NumPy, float64 checks).

    ``tris`` is the scene's (n_tri, 3, 3) corners; distances of missed rays are ignored (inf, or Embree's
    untouched ``tfar``).
    """
    tris = np.asarray(tris, np.float64)
    tri, tri_ref = np.asarray(tri), np.asarray(tri_ref)
    t, t_ref = np.asarray(t, np.float64), np.asarray(t_ref, np.float64)
    h, h_ref = tri >= 0, tri_ref >= 0
    both = h & h_ref
    extent = float(np.linalg.norm(np.ptp(tris.reshape(-1, 3), axis=0)))
    same_t = ~h & ~h_ref
    same_t[both] = np.abs(t[both] - t_ref[both]) <= rtol_t * (np.abs(t_ref[both]) + extent)
    return HitComparison(
        same_hit=h == h_ref,
        same_id=tri == tri_ref,
        tie=verified_ties(tris, o, d, tri, tri_ref),
        same_t=same_t,
    )


def assert_same_hits(scene, o, d, hit, ref, *, label: str) -> HitComparison:
    """Every ray agrees with ``ref``: hit/miss, distance, and triangle up to verified ties.

    The triangle ids themselves are not compared beyond that: a caster may report either of two tied
    triangles (the module docstring). Returns the comparison, whose ``same_id_share`` may be reported.
    """
    tris = np.asarray(scene.vertices, np.float64)[np.asarray(scene.faces)]
    tri, t = np.asarray(hit.tri), np.asarray(hit.t, np.float64)
    tri_r, t_r = np.asarray(ref.tri), np.asarray(ref.t, np.float64)
    c = compare_hits(tris, o, d, tri, t, tri_r, t_r)
    np.testing.assert_array_equal(tri >= 0, tri_r >= 0, err_msg=f"{label}: hit/miss differs")
    bad = np.flatnonzero(~(c.same_id | c.tie))
    assert bad.size == 0, (
        f"{label}: {bad.size} rays hit a different triangle that is not a verified coplanar tie (rays "
        f"{bad[:5]}: {tri[bad[:5]]} vs {tri_r[bad[:5]]}; same-id share {c.same_id_share:.4f}, "
        f"{int(c.tie.sum())} verified ties)"
    )
    h = tri >= 0
    extent = float(np.linalg.norm(np.ptp(tris.reshape(-1, 3), axis=0)))
    np.testing.assert_allclose(t[h], t_r[h], rtol=T_RTOL, atol=T_RTOL * extent, err_msg=label)
    assert c.agree.all()  # the checks above, as compare_hits judges them (the benchmark's key)
    # same triangle → same material; at a tie the two triangles may carry different materials
    np.testing.assert_array_equal(np.asarray(hit.material)[c.same_id], np.asarray(ref.material)[c.same_id])
    return c
