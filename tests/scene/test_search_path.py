"""Scene names resolve through the documented search path; ``list_scenes`` and the CLI report them."""

import os
from pathlib import Path

import pytest

from probeplace.cli import main
from probeplace.scene import (
    BUILTIN_SCENES,
    SCENE_PATH_ENV,
    list_scenes,
    load_scene,
    scene_search_path,
)
from probeplace.scene._search import _REPO_ROOT

_TRI_OBJ = "v 0 0 0\nv {s} 0 0\nv 0 {s} 0\nf 1 2 3\n"


def _write(folder: Path, name: str, size: float) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    p = folder / f"{name}.obj"
    p.write_text(_TRI_OBJ.format(s=size))
    return p


def _size(scene) -> float:
    return float(scene.bounds[1, 0])  # each test file is a triangle with its own size


@pytest.fixture
def clean_env(monkeypatch, tmp_path):
    monkeypatch.delenv(SCENE_PATH_ENV, raising=False)
    monkeypatch.chdir(tmp_path)  # so ./scenes is the test's own folder
    return tmp_path


def test_env_var_is_searched(clean_env, monkeypatch):
    a, b = clean_env / "a", clean_env / "b"
    _write(b, "thing", 2.0)
    monkeypatch.setenv(SCENE_PATH_ENV, os.pathsep.join([str(a), str(b)]))
    assert _size(load_scene("thing")) == 2.0
    _write(a, "thing", 3.0)  # an earlier folder in the variable wins
    assert _size(load_scene("thing")) == 3.0


def test_order_argument_then_env_then_cwd_scenes(clean_env, monkeypatch):
    arg, env, cwd = clean_env / "arg", clean_env / "env", clean_env / "scenes"
    _write(cwd, "thing", 1.0)
    assert _size(load_scene("thing")) == 1.0
    _write(env, "thing", 2.0)
    monkeypatch.setenv(SCENE_PATH_ENV, str(env))
    assert _size(load_scene("thing")) == 2.0
    _write(arg, "thing", 3.0)
    assert _size(load_scene("thing", search_path=[arg])) == 3.0
    assert _size(load_scene("thing", search_path=str(arg))) == 3.0  # os.pathsep string form
    dirs = scene_search_path([arg])
    assert dirs[:3] == [arg, env, Path("scenes")]


def test_shared_folder_is_last_when_present(clean_env):
    shared = _REPO_ROOT.parent / "shared" / "scenes"
    dirs = scene_search_path()
    if shared.is_dir():
        assert dirs[-1] == shared
    else:
        assert shared not in dirs


def test_extension_order_within_a_folder(clean_env):
    folder = clean_env / "scenes"
    _write(folder, "dup", 1.0)
    import trimesh

    tm = trimesh.Trimesh([[0, 0, 0], [5.0, 0, 0], [0, 5.0, 0]], [[0, 1, 2]], process=False)
    (folder / "dup.ply").write_bytes(tm.export(file_type="ply"))
    assert _size(load_scene("dup")) == 1.0  # .obj comes before .ply
    entries = [e for e in list_scenes() if e.name == "dup"]
    assert len(entries) == 1 and entries[0].source.endswith("dup.obj")


def test_builtin_wins_over_file_of_same_name(clean_env):
    _write(clean_env / "scenes", "cornell_box", 7.0)
    assert load_scene("cornell_box").n_triangles == 36  # the built-in
    s = load_scene(clean_env / "scenes" / "cornell_box.obj")  # a path loads the file
    assert _size(s) == 7.0


def test_list_scenes_reports_builtins_and_files(clean_env):
    p = _write(clean_env / "scenes", "extra", 1.0)
    entries = list_scenes()
    builtin = {e.name: e for e in entries if e.kind == "builtin"}
    assert set(builtin) == set(BUILTIN_SCENES) >= {"cornell_box", "temple", "rooms", "courtyard"}
    assert builtin["temple"].source == "probeplace.scene.builtin._temple"
    files = {e.name: e for e in entries if e.kind == "file"}
    assert files["extra"].source == str(Path("scenes") / p.name)


def test_cli_scenes_lists_them(clean_env, capsys):
    _write(clean_env / "scenes", "extra", 1.0)
    assert main(["scenes"]) == 0
    out = capsys.readouterr().out
    for name in ("cornell_box", "temple", "rooms", "courtyard", "extra"):
        assert name in out
