"""Bad scene input gives a SceneError naming the file and the problem, never a deep traceback."""

import logging

import numpy as np
import pytest

from probeplace._core import SceneError
from probeplace.scene import load_scene
from tests.helpers import shared_scene_path
from tests.scene.gltf_util import write_glb

_RANDOM = np.random.default_rng(1234).integers(0, 256, size=4096, dtype=np.uint8).tobytes()


def test_missing_file(tmp_path):
    with pytest.raises(SceneError, match="not found"):
        load_scene(tmp_path / "nope.glb")


def test_unsupported_extension(tmp_path):
    p = tmp_path / "mesh.stl"
    p.write_bytes(b"solid x\nendsolid x\n")
    with pytest.raises(SceneError, match=r"unsupported scene file extension '\.stl'"):
        load_scene(p)


@pytest.mark.parametrize("ext", [".glb", ".gltf", ".obj", ".ply"])
def test_random_bytes(tmp_path, ext):
    p = tmp_path / f"garbage{ext}"
    p.write_bytes(_RANDOM)
    with pytest.raises(SceneError, match="garbage") as info:
        load_scene(p)
    assert any(w in str(info.value) for w in ("corrupt", "not a GLB", "could not read", "no triangles"))


def test_truncated_glb(tmp_path):
    data = shared_scene_path("cornell_box.glb").read_bytes()
    p = tmp_path / "cut.glb"
    p.write_bytes(data[: len(data) // 2])
    with pytest.raises(SceneError, match=f"truncated GLB: the header declares {len(data)} bytes"):
        load_scene(p)


def test_truncated_glb_inside_header(tmp_path):
    p = tmp_path / "stub.glb"
    p.write_bytes(b"glTF\x02\x00")
    with pytest.raises(SceneError, match="truncated GLB"):
        load_scene(p)


def test_obj_without_triangles(tmp_path):
    p = tmp_path / "points.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(SceneError, match="no triangles"):
        load_scene(p)


def test_glb_without_triangles(tmp_path):
    p = write_glb(tmp_path / "empty.glb", [], [{"name": "nothing"}], [])
    with pytest.raises(SceneError, match="no triangles"):
        load_scene(p)


def test_ply_point_cloud_has_no_triangles(tmp_path):
    p = tmp_path / "cloud.ply"
    p.write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "end_header\n0 0 0\n1 0 0\n0 1 0\n"
    )
    with pytest.raises(SceneError, match="no triangles"):
        load_scene(p)


@pytest.mark.parametrize("bad", ["nan", "inf"])
def test_non_finite_vertices(tmp_path, bad):
    p = tmp_path / "bad.obj"
    p.write_text(f"v 0 0 0\nv 1 0 0\nv 0 {bad} 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\n")
    with pytest.raises(SceneError, match="NaN or infinite"):
        load_scene(p)


def test_non_finite_vertices_glb(tmp_path):
    verts = np.array([[0, 0, 0], [1, 0, 0], [0, np.nan, 0]], np.float32)
    p = write_glb(
        tmp_path / "nan.glb", [(verts, np.array([[0, 1, 2]]), None)], [{"name": "n", "mesh": 0}], []
    )
    with pytest.raises(SceneError, match="NaN or infinite"):
        load_scene(p)


def test_degenerate_triangles_are_dropped_and_counted(tmp_path, caplog):
    # 2 good triangles, 1 with a repeated vertex, 1 with three collinear vertices
    p = tmp_path / "degen.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nv 0 0 1\nf 1 2 3\nf 1 2 5\nf 1 1 3\nf 1 2 4\n")
    with caplog.at_level(logging.WARNING, logger="probeplace.scene._build"):
        s = load_scene(p)
    assert s.n_triangles == 2
    assert "dropped 2 degenerate (zero-area) triangles of 4" in caplog.text


def test_all_triangles_degenerate(tmp_path):
    p = tmp_path / "flat.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    with pytest.raises(SceneError, match="degenerate"):
        load_scene(p)


def test_bad_mtl_value_names_the_line(tmp_path):
    (tmp_path / "m.mtl").write_text("newmtl a\nKd 0.5 oops 0.5\n")
    p = tmp_path / "m.obj"
    p.write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n")
    with pytest.raises(SceneError, match=r"m\.mtl:2: bad number"):
        load_scene(p)


def test_negative_emission_rejected(tmp_path):
    (tmp_path / "e.mtl").write_text("newmtl a\nKe -1 0 0\n")
    p = tmp_path / "e.obj"
    p.write_text("mtllib e.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n")
    with pytest.raises(SceneError, match="emission"):
        load_scene(p)


def test_gltf_json_not_gltf2(tmp_path):
    p = tmp_path / "old.gltf"
    p.write_text('{"asset": {"version": "1.0"}}')
    with pytest.raises(SceneError, match=r"not a glTF 2\.0 document"):
        load_scene(p)


def test_unknown_name_lists_search_path(tmp_path):
    with pytest.raises(SceneError, match="unknown scene 'no_such_scene'") as info:
        load_scene("no_such_scene", search_path=[tmp_path])
    assert str(tmp_path) in str(info.value) and "cornell_box" in str(info.value)
