"""transform_scene against the rigid-motion invariants."""

import jax.numpy as jnp
import numpy as np
import pytest

from probeplace.scene import axis_angle_rotation, load_scene, transform_scene


@pytest.fixture(scope="module")
def temple():
    return load_scene("temple")


def _rt():
    return axis_angle_rotation([0.3, 1.0, -0.2], 0.4), np.array([1.5, -0.25, 3.0])


def test_distances_preserved_and_points_moved(temple):
    r, t = _rt()
    out = transform_scene(temple, r, t)
    v0, v1 = np.asarray(temple.vertices, np.float64), np.asarray(out.vertices, np.float64)
    # float32 storage of coordinates up to ~22 m: a few ulps of 22
    atol = 8 * 22 * float(np.finfo(np.float32).eps)
    np.testing.assert_allclose(v1, v0 @ r.T + t, atol=atol)
    i, j = np.random.default_rng(0).integers(0, len(v0), size=(2, 500))
    np.testing.assert_allclose(
        np.linalg.norm(v1[i] - v1[j], axis=1), np.linalg.norm(v0[i] - v0[j], axis=1), atol=2 * atol
    )
    assert out.vertices.dtype == temple.vertices.dtype == jnp.float32


def test_normals_views_and_sun_rotated(temple):
    r, t = _rt()
    out = transform_scene(temple, r, t)
    eps = 8 * float(np.finfo(np.float32).eps)  # unit vectors, a few float32 roundings
    np.testing.assert_allclose(
        np.asarray(out.corner_normals), np.asarray(temple.corner_normals) @ r.T, atol=eps
    )
    # the winding still agrees with the (rotated) normals: front faces stay front faces
    tri = np.asarray(out.triangles, np.float64)
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert np.all(np.einsum("ij,ij->i", fn, np.asarray(out.corner_normals, np.float64).mean(axis=1)) > 0)
    for a, b in zip(temple.views, out.views, strict=True):
        assert a.name == b.name
        np.testing.assert_allclose(np.asarray(b.position), np.asarray(a.position) @ r.T + t, atol=1e-5)
        np.testing.assert_allclose(np.asarray(b.look_at), np.asarray(a.look_at) @ r.T + t, atol=1e-5)
        np.testing.assert_allclose(np.asarray(b.up), np.asarray(a.up) @ r.T, atol=eps)
    np.testing.assert_allclose(
        np.asarray(out.sun.direction), np.asarray(temple.sun.direction) @ r.T, atol=eps
    )
    np.testing.assert_array_equal(np.asarray(out.sun.radiance), np.asarray(temple.sun.radiance))
    np.testing.assert_array_equal(np.asarray(out.faces), np.asarray(temple.faces))


def test_identity_is_a_no_op(cornell):
    out = transform_scene(cornell)
    np.testing.assert_array_equal(np.asarray(out.vertices), np.asarray(cornell.vertices))
    assert out.sun is None


def test_translation_only_keeps_normals(cornell):
    out = transform_scene(cornell, translation=[10.0, 0.0, 0.0])
    np.testing.assert_array_equal(np.asarray(out.corner_normals), np.asarray(cornell.corner_normals))
    np.testing.assert_allclose(
        np.asarray(out.bounds) - np.asarray(cornell.bounds), [[10, 0, 0]] * 2, atol=1e-4
    )


def test_axis_angle_rotation_is_proper_and_correct():
    r = axis_angle_rotation([0.0, 0.0, 2.0], np.pi / 2)
    np.testing.assert_allclose(r @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, rtol=1e-15)


def test_bad_rotation_rejected(cornell):
    with pytest.raises(ValueError, match="proper rotation"):
        transform_scene(cornell, np.diag([1.0, 1.0, -1.0]))  # a reflection would flip every winding
    with pytest.raises(ValueError, match="proper rotation"):
        transform_scene(cornell, 2.0 * np.eye(3))
    with pytest.raises(ValueError, match="3×3"):
        transform_scene(cornell, np.eye(4))
    with pytest.raises(ValueError, match="translation"):
        transform_scene(cornell, translation=[0.0, np.nan, 0.0])
