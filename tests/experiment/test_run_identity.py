"""Issue 31: a run's identity covers every input. A finished run is skipped only when it ran with the same
config *and* the same inputs (``inputs.json``: the scene file's and its MTL's hashes, the resolved sidecar,
the code version); a changed sidecar sun, scene file or code version is refused naming the keys (or redone
with ``redo=stale``), and a run that recorded no inputs is refused, not guessed. The runner script says so
before any run starts, and answers ``scene=<file>`` with the ``scene.name=`` form.

One tiny run (the resume test's settings: placement only, skeleton, 2 probes, on the sidecar tests' room)
is made once for the module; the checks that follow rerun it or refuse it."""

from __future__ import annotations

import hashlib
import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from omegaconf import OmegaConf

import probeplace.experiment._inputs as inputs_mod
from probeplace._core import ConfigError
from probeplace.experiment import run, run_dir, to_config
from probeplace.experiment._inputs import run_inputs
from tests.scene.sidecar_util import write_room_obj

from ._util import ROOT, compose

SCRIPT = ROOT / "experiments" / "run.py"
SUN = "sun: {azimuth: 90, elevation: 35, irradiance: 8}\nsky: daylight\n"
LOWER_SUN = "sun: {azimuth: 90, elevation: 20, irradiance: 8}\nsky: daylight\n"


def _overrides(folder: Path, *extra: str) -> list[str]:
    """The command line of the tiny run (as experiments/run.py takes it)."""
    return [
        f"scene.name={folder / 'room.obj'}",
        "bake=none",
        "eval=none",
        "placer.budget=2",
        "progress=false",
        "name=identity",
        f"results_dir={folder / 'results'}",
        *extra,
    ]


def _cfg(folder: Path, *extra: str):
    """The config experiments/run.py composes for that command line."""
    return to_config(OmegaConf.to_container(compose(_overrides(folder, *extra)), resolve=True))


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A scene folder (room.obj + room.mtl + its sidecar with a sun) and one finished run of it."""
    folder = tmp_path_factory.mktemp("identity")
    write_room_obj(folder)
    (folder / "room.probeplace.yaml").write_text(SUN)
    res = run(_cfg(folder))
    assert not res.skipped
    return folder


@pytest.fixture
def scene_files(finished):
    """The finished run's folder; every scene file (and the run's inputs.json) restored afterwards."""
    out = run_dir(_cfg(finished))
    saved = {p: p.read_bytes() for p in [*finished.glob("room.*"), out / "inputs.json"]}
    yield finished
    for p, data in saved.items():
        p.write_bytes(data)


def _script(folder: Path, *args: str) -> subprocess.CompletedProcess:
    """``python experiments/run.py ...`` as a user runs it."""
    argv = [f"hydra.run.dir={folder / 'hydra'}", *args]
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "JAX_PLATFORMS": "cpu"}
    return subprocess.run(
        [sys.executable, str(SCRIPT), *argv], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300
    )


def test_a_changed_sidecar_sun_is_not_skipped_by_the_runner(scene_files):
    """The issue's must-show: after the sidecar's sun changed, rerunning the finished run with the same
    command does not answer "skipped (finished)"; it is refused (one line, status 2, before any run)
    naming the key and both values. Unchanged, the same command still skips."""
    folder = scene_files
    same = _script(folder, *_overrides(folder))
    assert same.returncode == 0, same.stderr
    assert same.stdout.strip().endswith("room__skeleton__b2__s0: skipped (finished)"), same.stdout
    print("unchanged rerun:", same.stdout.strip())

    (folder / "room.probeplace.yaml").write_text(LOWER_SUN)
    moved = _script(folder, *_overrides(folder))
    print("after the sun change: status", moved.returncode, moved.stdout.strip(), moved.stderr.strip())
    assert "skipped (finished)" not in moved.stdout
    assert moved.returncode == 2, moved.stderr
    lines = moved.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("probeplace: error: "), moved.stderr
    assert (
        "is a finished run with different inputs (scene.config.sun.elevation_deg (35.0 → 20.0))" in lines[0]
    )
    assert "redo=stale" in lines[0]


def test_run_skips_only_a_run_with_the_same_inputs(scene_files):
    """``run`` itself (Python, no precheck): unchanged skips; a reformatted sidecar with the same values
    skips (resolved values, not text); a changed sun, MTL or code version is refused naming the keys;
    ``redo=stale`` redoes it and records the new inputs; the redone run then skips."""
    folder = scene_files
    cfg = _cfg(folder)
    assert run(cfg).skipped
    # the same sun and sky, spelt otherwise: the same run
    (folder / "room.probeplace.yaml").write_text(
        "# a comment\nsky: daylight\nsun:\n  el: 35\n  az: 90.0\n  irradiance: [8, 8, 8]\n"
    )
    assert run(cfg).skipped

    (folder / "room.probeplace.yaml").write_text(LOWER_SUN)
    with pytest.raises(
        ConfigError, match=r"different inputs \(scene\.config\.sun\.elevation_deg \(35\.0 → 20\.0\)\)"
    ):
        run(cfg)
    (folder / "room.probeplace.yaml").write_text(SUN)

    mtl = folder / "room.mtl"
    mtl.write_text(mtl.read_text().replace("Kd 0.5 0.4 0.3", "Kd 0.5 0.4 0.2"))
    with pytest.raises(ConfigError, match=r"different inputs \(scene\.references\.room\.mtl \("):
        run(cfg)
    (folder / "room.obj").write_text((folder / "room.obj").read_text() + "# touched\n")
    with pytest.raises(ConfigError, match=r"scene\.references\.room\.mtl .*; scene\.sha256 \("):
        run(cfg)


def test_a_new_code_version_is_refused_and_redo_stale_redoes_it(scene_files, monkeypatch):
    folder = scene_files
    monkeypatch.setattr(inputs_mod, "RESULTS_VERSION", inputs_mod.RESULTS_VERSION + 1)
    v = inputs_mod.RESULTS_VERSION
    with pytest.raises(ConfigError, match=rf"different inputs \(code\.results_version \({v - 1} → {v}\)\)"):
        run(_cfg(folder))
    res = run(_cfg(folder, "redo=stale"))
    assert not res.skipped
    recorded = json.loads((res.out_dir / "inputs.json").read_text())
    assert recorded["code"]["results_version"] == v
    assert recorded["scene"]["config"]["sun"]["elevation_deg"] == 35.0
    assert recorded["scene_loaded"]["sun"]["elevation_deg"] == pytest.approx(35.0, abs=1e-4)
    assert not list(res.out_dir.parent.glob(".*")), "no partial or replaced folder is left"
    assert run(_cfg(folder)).skipped  # redo is not part of the identity


def test_a_run_without_recorded_inputs_is_refused_not_guessed(scene_files):
    """A run written before inputs were recorded cannot be checked: refused with the way out, at once
    (no traceback), and ``redo=all`` (or ``force``) redoes it."""
    folder = scene_files
    cfg = _cfg(folder)
    (run_dir(cfg) / "inputs.json").unlink()
    with pytest.raises(
        ConfigError,
        match=r"inputs \(scene file hash, resolved sidecar, code version\) were not recorded.*redo=stale",
    ):
        run(cfg)
    (run_dir(cfg) / "inputs.json").write_text("{not json")
    with pytest.raises(ConfigError, match=r"inputs\.json cannot be read"):
        run(cfg)


def test_a_builtin_scene_is_named_by_name_parameters_config_and_code():
    """A built-in's identity: its name, the generator's parameters (none today), the resolved overrides
    (values: ``az`` read as ``azimuth_deg``) and the code version; nothing is loaded."""
    cfg = to_config({"scene": {"overrides": {"sun": {"az": 10, "el": 20}}}})
    got = run_inputs(cfg.scene)
    assert got["code"] == {"results_version": inputs_mod.RESULTS_VERSION, "probeplace": "0.1.0"}
    assert {k: got["scene"][k] for k in ("kind", "name", "parameters")} == {
        "kind": "builtin",
        "name": "cornell_box",
        "parameters": {},
    }
    sun = got["scene"]["config"]["sun"]
    assert (sun["azimuth_deg"], sun["elevation_deg"], sun["direction"]) == (10.0, 20.0, None)
    assert run_inputs(to_config({}).scene)["scene"]["config"]["sun"] is None


def test_a_moved_scene_folder_is_the_same_scene(tmp_path):
    """``path`` is recorded, not compared: the same files elsewhere give the same compared inputs."""
    a, b = tmp_path / "a", tmp_path / "b"
    for d in (a, b):
        d.mkdir()
        write_room_obj(d)
        (d / "room.probeplace.yaml").write_text(SUN)
    ia = run_inputs(to_config({"scene": {"name": str(a / "room.obj")}}).scene)
    ib = run_inputs(to_config({"scene": {"name": str(b / "room.obj")}}).scene)
    assert ia["scene"].pop("path") != ib["scene"].pop("path")
    assert ia == ib


@pytest.fixture
def runner():
    spec = importlib.util.spec_from_file_location("probeplace_experiments_run_identity", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_scene_option_for_a_file_scene_hints_at_scene_name(runner, tmp_path, capsys, no_slow_work):
    """``scene=room`` looks for configs/scene/room.yaml; the one line says a file is ``scene.name=room``."""
    from hydra.core.global_hydra import GlobalHydra

    GlobalHydra.instance().clear()
    with pytest.raises(SystemExit) as e:
        runner._precheck([f"results_dir={tmp_path}", "scene=room"])
    assert e.value.code == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert "Could not find 'scene/room'" in lines[0] and "given as scene.name=room" in lines[0]
    GlobalHydra.instance().clear()
    with pytest.raises(SystemExit):
        runner._precheck([f"results_dir={tmp_path}", "method=nosuch"])
    assert "scene.name" not in capsys.readouterr().err  # only the scene group gets the hint


def test_the_shared_sponza_is_identified_by_its_file():
    """On the shared scenes (skipped where they are absent): a name on the search path resolves to its
    file, hashed, with KNOWN_SCENES' sun resolved."""
    shared = ROOT.parent / "shared" / "scenes" / "crytek_sponza.glb"
    if not shared.is_file():
        pytest.skip(f"{shared} is absent (the shared scenes live beside the checkout)")
    got = run_inputs(to_config({"scene": {"name": "crytek_sponza"}}).scene)["scene"]
    assert got["kind"] == "file" and Path(got["path"]).resolve() == shared.resolve()
    assert got["sha256"] == hashlib.sha256(shared.read_bytes()).hexdigest() and got["references"] == {}
    assert (got["config"]["sun"]["azimuth_deg"], got["config"]["sun"]["elevation_deg"]) == (170.0, 65.0)
