"""Atomic writes and EXR files (``probeplace._core.files._io``): the old file survives a failed write, no
temporary file is left behind, new files get the umask's permissions, EXR channels round-trip."""

from __future__ import annotations

import json
import os
import stat

import numpy as np
import pytest

from probeplace._core import (
    atomic_path,
    read_exr,
    write_atomic,
    write_bytes_atomic,
    write_exr,
    write_json_atomic,
    write_text_atomic,
)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def test_json_text_is_indent_one_with_a_trailing_newline(tmp_path):
    doc = {"b": [1, 2.5], "a": {"x": True}}
    path = write_json_atomic(tmp_path / "sub" / "doc.json", doc)  # the folder is created
    assert path.read_text() == json.dumps(doc, indent=1) + "\n"
    assert list(json.loads(path.read_text())) == ["b", "a"]  # key order as built


@pytest.mark.parametrize(("doc", "error"), [({"v": float("nan")}, ValueError), ({"v": object()}, TypeError)])
def test_failed_serialisation_keeps_the_old_file_and_leaves_no_temporary(tmp_path, doc, error):
    path = write_json_atomic(tmp_path / "doc.json", {"v": 1})
    before = path.read_bytes()
    with pytest.raises(error):
        write_json_atomic(path, doc)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["doc.json"]


def test_a_writer_that_raises_halfway_keeps_the_old_file(tmp_path):
    path = write_bytes_atomic(tmp_path / "a.bin", b"old")

    def half(f):
        f.write(b"new, but only in part")
        raise RuntimeError("disk on fire")

    with pytest.raises(RuntimeError, match="disk on fire"):
        write_atomic(path, half)
    assert path.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.bin"]


def test_stream_writer_replaces_the_file(tmp_path):
    path = tmp_path / "a.npz"
    write_atomic(path, lambda f: np.savez(f, x=np.arange(3)))
    write_atomic(path, lambda f: np.savez(f, x=np.arange(5)))
    with np.load(path) as z:
        np.testing.assert_array_equal(z["x"], np.arange(5))
    assert [p.name for p in tmp_path.iterdir()] == ["a.npz"]


def test_new_files_get_the_umask_permissions_not_0600(tmp_path):
    path = write_text_atomic(tmp_path / "t.txt", "héllo\n")
    assert path.read_text(encoding="utf-8") == "héllo\n"
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~_umask()


def test_atomic_path_keeps_the_suffix_and_renames_on_success(tmp_path):
    target = tmp_path / "scene.usda"
    with atomic_path(target, suffix=".tmp.usda") as tmp:
        assert tmp.parent == tmp_path and tmp.name.startswith(".scene.usda.") and tmp.suffix == ".usda"
        assert tmp.is_file() and not target.exists()  # nothing visible until the block ends
        tmp.write_text("#usda 1.0\n")
    assert target.read_text() == "#usda 1.0\n"
    assert [p.name for p in tmp_path.iterdir()] == ["scene.usda"]


def test_atomic_path_removes_the_temporary_on_error(tmp_path):
    with pytest.raises(KeyError), atomic_path(tmp_path / "x.exr", suffix=".tmp.exr") as tmp:
        tmp.write_bytes(b"partial")
        raise KeyError("stop")
    assert list(tmp_path.iterdir()) == []


def test_exr_channels_round_trip_separate_and_grouped(tmp_path):
    rng = np.random.default_rng(0)
    r, g = rng.random((4, 5)), rng.random((4, 5))
    path = write_exr(tmp_path / "two.exr", {"R": r, "G": g})
    got = read_exr(path)
    assert set(got) == {"R", "G"}
    np.testing.assert_array_equal(got["R"], r.astype(np.float32))  # float32 storage: exact after cast
    np.testing.assert_array_equal(got["G"], g.astype(np.float32))

    rgb, extra = rng.random((3, 2, 3)), rng.random((3, 2, 3))
    path = write_exr(tmp_path / "layers.exr", {"RGB": rgb, "direct.RGB": extra})
    got = read_exr(path, separate_channels=False)
    assert set(got) == {"RGB", "direct.RGB"}
    np.testing.assert_array_equal(got["RGB"], rgb.astype(np.float32))
    np.testing.assert_array_equal(got["direct.RGB"], extra.astype(np.float32))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["layers.exr", "two.exr"]
