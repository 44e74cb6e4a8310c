"""The built-in Cornell box against the published data and the shared glTF copy."""

import numpy as np
import trimesh

from tests.helpers import shared_scene_path


def _area(tris):
    return 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)


def test_cornell_bounds_and_light(cornell):
    b = np.asarray(cornell.bounds)
    np.testing.assert_allclose(b, [[0, 0, 0], [556.0, 548.8, 559.2]], atol=1e-4)
    assert cornell.n_triangles == 36
    light = np.asarray(cornell.triangles)[np.asarray(cornell.emissive_tris)]
    # 130 mm × 105 mm quad (Cornell data page)
    np.testing.assert_allclose(_area(light).sum(), 130.0 * 105.0, rtol=1e-6)
    # the light faces down
    n = np.asarray(cornell.corner_normals)[np.asarray(cornell.emissive_tris)]
    np.testing.assert_allclose(n[..., 1], -1.0, atol=1e-6)
    assert cornell.has_light


def test_cornell_walls_face_inward_blocks_outward(cornell):
    tris = np.asarray(cornell.triangles, np.float64)
    fn = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    centre = tris.mean(axis=1)
    parts = np.asarray(cornell.tri_part)
    for pid, name in enumerate(cornell.part_names):
        sel = parts == pid
        if name.endswith("block"):
            ref = centre[sel] - tris[sel].reshape(-1, 3).mean(axis=0)  # away from the block's centre
        elif name == "light":
            continue
        else:
            ref = np.array([278.0, 274.4, 279.6]) - centre[sel]  # toward the box's centre
        assert np.all(np.einsum("ij,ij->i", fn[sel], ref) > 0), name


def test_cornell_matches_shared_gltf(cornell):
    glb = trimesh.load(shared_scene_path("cornell_box.glb"), force="scene")
    tris = np.asarray(cornell.triangles, np.float64)
    parts = np.asarray(cornell.tri_part)
    for name, geom in glb.geometry.items():
        mine = tris[parts == cornell.part_names.index(name)]
        theirs = geom.vertices[geom.faces]
        # same corners, same area, same orientation (the quads may be split on the other diagonal)
        np.testing.assert_allclose(
            np.unique(mine.reshape(-1, 3).round(3), axis=0), np.unique(theirs.reshape(-1, 3).round(3), axis=0)
        )
        np.testing.assert_allclose(_area(mine).sum(), _area(theirs).sum(), rtol=1e-9)
        fm = np.cross(mine[:, 1] - mine[:, 0], mine[:, 2] - mine[:, 0]).sum(axis=0)
        ft = np.cross(theirs[:, 1] - theirs[:, 0], theirs[:, 2] - theirs[:, 0]).sum(axis=0)
        np.testing.assert_allclose(fm, ft, rtol=1e-9, atol=1e-6)
        mat = cornell.tri_material[parts == cornell.part_names.index(name)][0]
        np.testing.assert_allclose(
            np.asarray(cornell.materials.base_color[mat]),
            geom.visual.material.baseColorFactor[:3] / 255.0,
            atol=1 / 255.0,  # trimesh quantises the factor to uint8
        )
