"""Mesh primitives: closed, outward-wound, with closed-form volumes and areas."""

import numpy as np
import pytest
import trimesh

from probeplace.scene._primitives import BOX_FACE_TRIS, box, cylinder, place, quad, rotation_y


def _tm(mesh):
    return trimesh.Trimesh(*mesh, process=False)


def test_box_is_closed_outward_with_exact_volume():
    m = _tm(box((1.0, -2.0, 0.5), (3.0, 1.0, 1.5)))
    assert m.is_watertight and m.is_winding_consistent
    np.testing.assert_allclose(m.volume, 2.0 * 3.0 * 1.0, rtol=1e-12)  # positive: outward normals
    # each face's triangles point along its named axis
    for name, tris in BOX_FACE_TRIS.items():
        axis = "xyz".index(name[1])
        sign = 1.0 if name[0] == "+" else -1.0
        np.testing.assert_allclose(m.face_normals[list(tris), axis], sign, atol=1e-12)


@pytest.mark.parametrize("n", [3, 13, 32])
def test_cylinder_is_closed_outward_with_prism_volume(n):
    r, h = 0.7, 2.5
    m = _tm(cylinder((1.0, 0.5, -2.0), r, h, n))
    assert m.is_watertight and m.is_winding_consistent
    # a regular n-gon prism: area (n/2) r² sin(2π/n) × h
    np.testing.assert_allclose(m.volume, 0.5 * n * r**2 * np.sin(2 * np.pi / n) * h, rtol=1e-12)
    assert m.faces.shape == (4 * n, 3)
    # side normals point away from the axis
    centre = np.array([1.0, 0.0, -2.0])
    side = np.abs(m.face_normals[:, 1]) < 1e-12
    radial = m.triangles_center[side] - centre
    radial[:, 1] = 0
    assert np.all(np.einsum("ij,ij->i", m.face_normals[side], radial) > 0)


def test_quad_faces_along_u_cross_v():
    v, f = quad((0.0, 2.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, -1.0))
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    np.testing.assert_allclose(n / np.linalg.norm(n, axis=1, keepdims=True), [[0, 1, 0]] * 2, atol=1e-12)
    np.testing.assert_allclose(_tm((v, f)).area, 1.0, rtol=1e-12)


def test_place_keeps_outward_winding_and_volume():
    m = _tm(place(box((0.0, 0.0, 0.0), (1.0, 2.0, 3.0)), rotation_y(0.7), (5.0, 0.0, -1.0)))
    assert m.is_watertight
    np.testing.assert_allclose(m.volume, 6.0, rtol=1e-12)


def test_bad_primitive_arguments():
    with pytest.raises(ValueError, match="lo < hi"):
        box((0.0, 0.0, 0.0), (1.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="radius"):
        cylinder((0.0, 0.0, 0.0), -1.0, 1.0)
    with pytest.raises(ValueError, match="parallel"):
        quad((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (2.0, 0.0, 0.0))
