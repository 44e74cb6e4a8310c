"""Surface samples: area conservation, on-triangle positions, normals, stratified counts, determinism."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from probeplace._core import ConfigError
from probeplace.geometry import default_sample_spacing, sample_surface
from probeplace.geometry._samples import sample_counts
from probeplace.scene import cornell_box
from tests.reference import sdf_scenes as ref


def _mesh(scene):
    tri = np.asarray(scene.vertices, np.float64)[np.asarray(scene.faces)]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return tri, 0.5 * np.linalg.norm(cross, axis=1), cross / np.linalg.norm(cross, axis=1, keepdims=True)


@pytest.mark.parametrize("which", ["cornell", "sphere"])
def test_samples_properties(which):
    scene = cornell_box() if which == "cornell" else ref.sphere_scene()
    spacing = 25.0 if which == "cornell" else 0.05
    s = sample_surface(scene, key=jax.random.key(0), spacing=spacing)
    tri, area, normal = _mesh(scene)
    t = np.asarray(s.tri)
    # Areas add up to the mesh area (float32 weights, float64 sum: relative error ≤ 2⁻²⁴ per weight).
    np.testing.assert_allclose(np.sum(np.asarray(s.area, np.float64)), area.sum(), rtol=1e-5)
    np.testing.assert_allclose(np.bincount(t, np.asarray(s.area, np.float64), len(area)), area, rtol=1e-5)
    # Every triangle has a sample, and counts follow area within the stratification bound |n − A/s²| < 1.
    counts = np.bincount(t, minlength=len(area))
    assert counts.min() >= 1
    assert np.all(np.abs(counts - area / spacing**2) < 1.0 + 1e-9)
    # On their triangles: zero distance to the plane, barycentrics in [0, 1] (float32 positions).
    p = np.asarray(s.position, np.float64)
    scale = np.abs(tri).max()
    plane = np.einsum("ij,ij->i", p - tri[t, 0], normal[t])
    np.testing.assert_allclose(plane, 0.0, rtol=0, atol=4 * np.finfo(np.float32).eps * scale)
    e1, e2, r = tri[t, 1] - tri[t, 0], tri[t, 2] - tri[t, 0], p - tri[t, 0]
    g = np.stack(
        [np.einsum("ij,ij->i", e1, e1), np.einsum("ij,ij->i", e1, e2), np.einsum("ij,ij->i", e2, e2)], 1
    )
    rhs = np.stack([np.einsum("ij,ij->i", r, e1), np.einsum("ij,ij->i", r, e2)], 1)
    det = g[:, 0] * g[:, 2] - g[:, 1] ** 2
    u = (g[:, 2] * rhs[:, 0] - g[:, 1] * rhs[:, 1]) / det
    v = (g[:, 0] * rhs[:, 1] - g[:, 1] * rhs[:, 0]) / det
    tol = 1e-4  # float32 positions relative to triangles of a few hundred ulps in size
    assert np.all(u >= -tol) and np.all(v >= -tol) and np.all(u + v <= 1 + tol)
    # Normals are the face normals; materials are the triangles'.
    np.testing.assert_allclose(np.asarray(s.normal), normal[t], rtol=0, atol=1e-6)
    np.testing.assert_array_equal(np.asarray(s.material), np.asarray(scene.tri_material)[t])
    assert s.position.dtype == np.float32 and s.tri.dtype == np.int32


def test_samples_deterministic_per_key():
    scene = cornell_box()
    a = sample_surface(scene, key=jax.random.key(1), spacing=30.0)
    b = sample_surface(scene, key=jax.random.key(1), spacing=30.0)
    c = sample_surface(scene, key=jax.random.key(2), spacing=30.0)
    np.testing.assert_array_equal(np.asarray(a.position), np.asarray(b.position))
    assert a.n != c.n or not np.array_equal(np.asarray(a.position), np.asarray(c.position))


def test_stratified_counts_unbiased():
    """Over the random offset u the expected count of a triangle is A/s² exactly (systematic sampling);
    checked on a fine grid of offsets, for triangles large enough not to be lifted to 1."""
    area = np.array([2.3, 0.7, 5.1, 1.49, 3.0])
    offsets = (np.arange(2000) + 0.5) / 2000
    mean = np.mean([sample_counts(area, 1.0, u) for u in offsets], axis=0)
    big = area >= 1.0
    np.testing.assert_allclose(mean[big], area[big], rtol=0, atol=1e-3)  # quadrature error of the offset grid


def test_default_spacing_and_errors():
    scene = cornell_box()
    s = default_sample_spacing(scene)
    _, area, _ = _mesh(scene)
    assert 0 < s and area.sum() / s**2 <= (1 << 18) * 1.01  # the sample budget at quality 1
    assert default_sample_spacing(scene, quality=2.0) < s
    with pytest.raises(ConfigError):
        sample_surface(scene, key=jax.random.key(0), spacing=-1.0)
    with pytest.raises(ConfigError):
        default_sample_spacing(scene, quality=float("inf"))


def test_requested_count_on_a_mesh_with_more_triangles_than_samples():
    """``min_one=False`` keeps ~A/s² samples where the one-per-triangle floor would more than double them
    (temple: 2,284 triangles for 1,500 samples), the weights still add up to the mesh area, and the
    weighted integral of position is unbiased (mean over keys vs the exact Σ A_t · centroid_t)."""
    from probeplace.geometry._samples import _tri_areas
    from probeplace.scene import load_scene

    scene = load_scene("temple")
    tri, area, _ = _tri_areas(scene)
    s = float(np.sqrt(area.sum() / 1500))
    assert sample_surface(scene, key=jax.random.key(0), spacing=s).n > 3000  # the floor's count
    exact = (area[:, None] * tri.mean(axis=1)).sum(0)
    est = []
    for k in range(24):
        smp = sample_surface(scene, key=jax.random.key(k), spacing=s, min_one=False)
        assert abs(smp.n - 1500) <= 1
        w = np.asarray(smp.area, np.float64)
        assert w.sum() == pytest.approx(area.sum(), rel=1e-6)
        est.append((w[:, None] * np.asarray(smp.position, np.float64)).sum(0))
    est = np.asarray(est)
    sem = est.std(0, ddof=1) / np.sqrt(len(est))
    assert np.all(np.abs(est.mean(0) - exact) <= 4 * sem + 1e-9 * np.abs(exact))
