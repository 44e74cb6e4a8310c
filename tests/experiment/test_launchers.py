"""Sweeps through Hydra's joblib launcher (local processes) and ray launcher (a local Ray instance):
both finish every run of a 2-point sweep into the same results layout. Slow: each starts fresh
processes that compile the placement."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from probeplace.experiment import iter_runs, load_runs

from ._util import ROOT

SWEEP = ["bake=none", "eval=none", "placer.budget=2", "progress=false", "seed=0,1"]


def _run_sweep(tmp_path, launcher: list[str]) -> subprocess.CompletedProcess:
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    cmd = [sys.executable, str(ROOT / "experiments" / "run.py"), "--multirun", *launcher]
    cmd += [f"results_dir={tmp_path}", "name=launch", *SWEEP]
    return subprocess.run(cmd, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=900)


def _check(tmp_path, proc):
    assert proc.returncode == 0, proc.stdout + proc.stderr
    runs = [p.name for p in iter_runs(tmp_path / "launch")]
    assert runs == [f"cornell_box__skeleton__b2__s{k}" for k in (0, 1)]
    assert all(r["n_probes"] <= 2 and r["coverage"] > 0 for r in load_runs(tmp_path / "launch"))


@pytest.mark.slow
def test_joblib_launcher(tmp_path):
    pytest.importorskip("hydra_plugins.hydra_joblib_launcher")
    _check(tmp_path, _run_sweep(tmp_path, ["hydra/launcher=joblib", "hydra.launcher.n_jobs=2"]))


@pytest.mark.slow
def test_ray_launcher_local_instance(tmp_path):
    pytest.importorskip("ray")
    pytest.importorskip("hydra_plugins.hydra_ray_launcher")
    # address=null: the launcher calls ray.init() and starts a local Ray instance for the sweep
    proc = _run_sweep(tmp_path, ["hydra/launcher=ray", "+hydra.launcher.ray.init.num_cpus=2"])
    _check(tmp_path, proc)
    assert "Started a local Ray instance" in proc.stdout + proc.stderr
