"""Issue 31: an OBJ or PLY file cut off at any byte loads or is refused with a SceneError naming the file
(``file:line`` where there is one), never another exception (a traceback from inside trimesh).

The oracle is exhaustive: every prefix of a small valid file of each flavour (OBJ with MTL, texture
coordinates, normals and negative indices; ASCII PLY with colours; binary PLY in both byte orders)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

from probeplace._core import SceneError
from probeplace.scene import load_scene
from tests.reliability.catalogue import TET_F, TET_V, tet_obj, tet_ply, tet_ply_binary

# Every statement kind the OBJ loader reads; the last vertices come after the faces that use them, so a
# cut there leaves a face pointing past the file's vertices.
OBJ = """# a tetrahedron
mtllib t.mtl
o tet
v 0 0 0
v 1.5 0 0
v 0 1 0 1.0
vt 0 0
vt 1 0
vt 0 1
vn 0 0 -1
usemtl red
f 1/1/1 3/3/1 2/2/1
f 1/1 2/2 -1
usemtl lamp
f 1//1 4//1 3//1
f 2 3 4
v 0 0 1
v 1.0 2.0 3.0
"""
MTL = "newmtl red\nKd 0.8 0.1 0.1\nnewmtl lamp\nKd 0.7 0.7 0.7\nKe 1 1 1\n"


def ply_colours() -> bytes:
    head = (
        "ply\nformat ascii 1.0\ncomment cut me\nelement vertex 4\nproperty float x\nproperty float y\n"
        "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
        "element face 4\nproperty list uchar int vertex_indices\nend_header\n"
    )
    rows = "".join(f"{a} {b} {c} 200 100 50\n" for a, b, c in TET_V)
    return (head + rows + "".join(f"3 {a} {b} {c}\n" for a, b, c in TET_F)).encode()


FILES = {
    "obj-full": (".obj", OBJ.encode()),
    "obj-tet": (".obj", tet_obj().encode()),
    "ply-ascii": (".ply", tet_ply().encode()),
    "ply-ascii-colours": (".ply", ply_colours()),
    "ply-binary-le": (".ply", tet_ply_binary("<")),
    "ply-binary-be": (".ply", tet_ply_binary(">")),
}


@pytest.mark.parametrize("name", list(FILES))
def test_every_cut_loads_or_is_a_scene_error(tmp_path: Path, name: str):
    ext, data = FILES[name]
    (tmp_path / "t.mtl").write_text(MTL)
    path = tmp_path / f"cut{ext}"
    loaded, refused = 0, 0
    logging.disable(logging.WARNING)  # a cut file logs (missing materials, trimesh warnings): not the point
    try:
        for n in range(len(data) + 1):
            path.write_bytes(data[:n])
            try:
                load_scene(path, sidecar=False)
                loaded += 1
            except SceneError as e:  # anything else propagates and fails the test, with its cut
                assert str(e).startswith(str(path)), (n, str(e))
                refused += 1
            except Exception as e:
                raise AssertionError(f"cut at byte {n} of {len(data)}: {type(e).__name__}: {e}") from e
    finally:
        logging.disable(logging.NOTSET)
    assert loaded >= 1 and refused >= 1  # the whole file loads; the empty file does not


@pytest.mark.parametrize(
    ("text", "where", "needle"),
    [
        (tet_obj() + "v 1.0 2.", ":9:", "vertex 'v 1.0 2.' has 2 numbers"),  # issue 31's own file
        (tet_obj() + "vn 0 0", ":9:", "normal"),
        (tet_obj() + "v 1 x 2\n", ":9:", "bad number"),
        (tet_obj() + "f 1 2 0\n", ":9:", "bad face corner '0'"),
        (tet_obj() + "f 1 2 -/3\n", ":9:", "bad face corner '-/3'"),
        (tet_obj().replace("v 0.0 0.0 1.0\n", ""), ":", "face uses vertex 4 but the file defines 3"),
    ],
    ids=["cut-vertex", "cut-normal", "bad-number", "index-0", "bad-corner", "missing-vertex"],
)
def test_obj_faults_name_the_line(tmp_path: Path, text: str, where: str, needle: str):
    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(SceneError) as info:
        load_scene(path, sidecar=False)
    assert str(info.value).startswith(f"{path}{where}") and needle in str(info.value), str(info.value)


@pytest.mark.parametrize(
    ("data", "needle"),
    [
        (tet_ply().encode().replace(b"element face 4", b"element face four"), ":7: bad PLY header line"),
        (tet_ply().encode().replace(b"property float y\n", b""), "no 'element vertex' with properties x"),
        (tet_ply().encode()[:-4], ":17: face row '3 1'"),
        (tet_ply().encode().replace(b"3 1 2 3\n", b""), "line 7 declares 4 face rows, the file ends after 3"),
        (tet_ply_binary("<")[:-1], "need at least 100 bytes after end_header; the file holds 99"),
    ],
    ids=["header-count", "no-y", "cut-row", "missing-row", "binary-short"],
)
def test_ply_faults_are_named(tmp_path: Path, data: bytes, needle: str):
    path = tmp_path / "bad.ply"
    path.write_bytes(data)
    with pytest.raises(SceneError, match=r"^" + str(path)) as info:
        load_scene(path, sidecar=False)
    assert needle in str(info.value), str(info.value)


def test_valid_files_load_whole(tmp_path: Path):
    """The checks refuse nothing valid: each file loads with every triangle."""
    (tmp_path / "t.mtl").write_text(MTL)
    for name, (ext, data) in FILES.items():
        path = tmp_path / f"{name}{ext}"
        path.write_bytes(data)
        scene = load_scene(path, sidecar=False)
        assert scene.n_triangles == 4, name
        assert np.isfinite(np.asarray(scene.bounds)).all()
