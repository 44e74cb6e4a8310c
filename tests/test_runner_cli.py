"""Issue 19, "the runner speaks like the CLI": ``experiments/run.py`` composes and checks every run of its
command line before Hydra starts one; an unknown key, a Hydra error (a misspelt key, a wrong type, a
missing option), an image too large for memory or an unwritable results folder is one line
``probeplace: error: ...`` naming the key, exit status 2. Ctrl-C is one line, status 130, and leaves no
run folder."""

from __future__ import annotations

import importlib.util
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "experiments" / "run.py"


@pytest.fixture(scope="module")
def runner():
    """experiments/run.py as a module (its ``__main__`` block does not run)."""
    spec = importlib.util.spec_from_file_location("probeplace_experiments_run", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture
def precheck(runner, capsys, no_slow_work):
    """``_precheck(argv)`` → its one error line (it must exit 2), or None when it passes."""
    from hydra.core.global_hydra import GlobalHydra

    def call(argv: list[str]) -> str | None:
        GlobalHydra.instance().clear()  # other tests of this process may leave Hydra initialised
        try:
            runner._precheck(argv)
        except SystemExit as e:
            assert e.code == 2, e.code
            lines = capsys.readouterr().err.strip().splitlines()
            assert len(lines) == 1 and lines[0].startswith("probeplace: error: "), lines
            return lines[0]
        return None

    return call


@pytest.mark.parametrize(
    ("override", "needles"),
    [
        ("+colour=red", ["colour", "not a key"]),
        ("placer.budgett=3", ["placer.budgett"]),
        ("seed=abc", ["seed=abc"]),
        ("scene=nosuch", ["scene/nosuch", "cornell_box"]),
        ("placer.budget=-3", ["placer.budget: must be 'auto' or a positive integer"]),
        ("eval.width=100000000", ["eval.width × eval.height", "bytes"]),
        ("bake.radiance_res=65536", ["bake.radiance_res=65536", "bytes"]),
        (
            "eval.view=nosuch",
            ["eval.view: scene 'cornell_box' has no view 'nosuch'; views: ['front', 'interior']"],
        ),
        ("+scene.overrides.colour=red", ["scene.overrides: colour: unknown key; known keys: cameras"]),
        ("scene.name=nosuch.obj", ["nosuch.obj", "not found"]),
    ],
)
def test_bad_keys_and_values_are_one_line(precheck, tmp_path, override, needles):
    extra = ["eval.height=100000000"] if override.startswith("eval.width") else []
    line = precheck([f"results_dir={tmp_path}", override, *extra])
    assert line is not None, f"{override} was accepted"
    for n in needles:
        assert n in line, line
    assert not any(tmp_path.iterdir())


def test_every_swept_value_is_checked(precheck, tmp_path):
    base = ["--multirun", f"results_dir={tmp_path}"]
    assert precheck([*base, "seed=0,1", "method=grid,skeleton"]) is None
    assert precheck([f"results_dir={tmp_path}", "+experiment=cornell_comparison"]) is None  # its own sweep
    assert "seed=abc" in precheck([*base, "seed=0,abc"])
    assert "method/nosuch" in precheck([*base, "method=grid,nosuch"])
    # without --multirun a sweep is Hydra's "ambiguous value" error, in one line
    assert "seed=0,1" in precheck([f"results_dir={tmp_path}", "seed=0,1"])


def test_every_scene_of_a_sweep_is_loaded_and_checked_first(precheck, tmp_path):
    """The scene of each run is loaded before the first run starts: a swept scene lacking the view is
    refused naming its views (not after the first scene's runs have finished)."""
    base = ["--multirun", f"results_dir={tmp_path}"]
    line = precheck([*base, "scene=cornell_box,rooms", "eval.view=front"])
    assert "eval.view: scene 'rooms' has no view 'front'; views: ['lit_room', 'doorway'" in line
    assert precheck([*base, "scene=cornell_box,rooms", "eval.view=front", "eval.enabled=false"]) is None


def test_a_file_scene_without_light_needs_its_sidecar_keys(precheck, tmp_path):
    """A dark room file is refused for a run that bakes, naming the sidecar keys; placement alone, or the
    same keys as ``scene.overrides`` (as for a sidecar beside the file), make it pass."""
    from tests.scene.sidecar_util import write_room_obj

    room = write_room_obj(tmp_path)
    run = [f"results_dir={tmp_path}/r", f"scene.name={room}", "eval.view=door"]
    line = precheck(run)
    assert "room.obj: the scene has no light" in line and "room.probeplace.yaml" in line
    assert precheck([*run, "bake.enabled=false", "eval.enabled=false"]) is None
    lit = [
        "+scene.overrides.sky=daylight",
        "+scene.overrides.cameras.door={position:[2,1.6,0.5],look_at:[2,1,5]}",
    ]
    assert precheck([*run, *lit]) is None
    (tmp_path / "room.probeplace.yaml").write_text(
        "sky: daylight\ncameras:\n  door: {position: [2, 1.6, 0.5], look_at: [2, 1, 5]}\n"
    )
    assert precheck(run) is None
    assert not (tmp_path / "r").exists()


def test_results_folder_must_be_writable(precheck, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    line = precheck([f"results_dir={blocker}/results"])
    assert "results_dir" in line and "is a file, not a folder" in line
    assert precheck(["--help"]) is None  # Hydra's own modes are left to Hydra


def _script(tmp_path: Path, *args: str) -> subprocess.Popen:
    """``python experiments/run.py args`` as a user runs it, with Python's own Ctrl-C handling even where
    this process ignores SIGINT (a background job)."""
    code = (
        "import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); import runpy; "
        f"sys.argv[0] = {str(SCRIPT)!r}; runpy.run_path(sys.argv[0], run_name='__main__')"
    )
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    argv = [f"hydra.run.dir={tmp_path}/hydra", f"results_dir={tmp_path}/r", *args]
    return subprocess.Popen([sys.executable, "-c", code, *argv], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)  # fmt: skip


def test_runner_refuses_an_unknown_key_in_one_line(tmp_path):
    """As a user runs it (the README's claim): ``+colour=red`` is refused, status 2, one line."""
    proc = _script(tmp_path, "+colour=red")
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("probeplace: error: colour:"), err
    assert not (tmp_path / "r").exists()


def test_runner_ctrl_c_is_one_line_and_leaves_no_run(tmp_path):
    proc = _script(tmp_path, "bake.enabled=false", "eval.enabled=false", "placer.budget=8")
    run_root = tmp_path / "r" / "default"
    deadline = time.monotonic() + 120
    while not (
        run_root.is_dir() and any(p.name.startswith(".") and "partial" in p.name for p in run_root.iterdir())
    ):
        assert proc.poll() is None, proc.communicate()[1]
        assert time.monotonic() < deadline, "the run never started"
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    lines = err.strip().splitlines()
    assert len(lines) <= 2 and lines[-1] == "probeplace: interrupted", err
    assert not [p for p in run_root.iterdir() if p.name != ".hydra"], list(run_root.iterdir())
