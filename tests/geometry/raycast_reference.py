"""Test helpers for ray casting: random rays, and a float64 NumPy check of hits against a reference.

Two casters may legitimately report different triangles for one ray when overlapping coplanar triangles
are hit at the same distance (the Cornell box's short block stands on the floor with its bottom face;
Sponza has overlapping wall quads). Such a difference counts as agreement only if the float64
Möller–Trumbore test confirms that the ray crosses *both* triangles at the reported distance.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np


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


def tie_or_same(scene, o, d, tri_a, t_a, tri_b, t_b, *, rtol: float = 1e-4):
    """Per ray: same triangle (or both miss), or a verified coplanar tie (see the module docstring)."""
    tri_a, tri_b = np.asarray(tri_a), np.asarray(tri_b)
    same = tri_a == tri_b
    both = (tri_a >= 0) & (tri_b >= 0) & ~same
    ok = same.copy()
    if both.any():
        tris = np.asarray(scene.vertices, np.float64)[np.asarray(scene.faces)]
        oo, dd = np.asarray(o, np.float64)[both], np.asarray(d, np.float64)[both]
        ta = ray_triangle_t(tris[tri_a[both]], oo, dd)
        tb = ray_triangle_t(tris[tri_b[both]], oo, dd)
        scale = np.maximum(1.0, np.abs(ta))
        ok[both] = np.abs(ta - tb) <= rtol * scale
    return same, ok


def assert_same_hits(scene, o, d, hit, ref, *, label: str, min_same_id: float = 0.99):
    """Every ray agrees with ``ref`` on hit/miss, on the triangle (up to verified ties) and on distance."""
    tri, t = np.asarray(hit.tri), np.asarray(hit.t, np.float64)
    tri_r, t_r = np.asarray(ref.tri), np.asarray(ref.t, np.float64)
    np.testing.assert_array_equal(tri >= 0, tri_r >= 0, err_msg=f"{label}: hit/miss differs")
    same, ok = tie_or_same(scene, o, d, tri, t, tri_r, t_r)
    assert ok.all(), f"{label}: {np.count_nonzero(~ok)} rays hit a different triangle (not a coplanar tie)"
    assert same.mean() >= min_same_id, f"{label}: only {same.mean():.4f} same triangle id"
    h = tri >= 0
    extent = float(np.linalg.norm(np.ptp(np.asarray(scene.vertices, np.float64), axis=0)))
    # float32 distances from two different intersection formulas: a few ulp of the scene extent apart
    np.testing.assert_allclose(t[h], t_r[h], rtol=1e-5, atol=1e-5 * extent, err_msg=label)
    np.testing.assert_array_equal(np.asarray(hit.material)[same], np.asarray(ref.material)[same])
