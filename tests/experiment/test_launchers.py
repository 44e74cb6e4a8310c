"""Sweeps through Hydra's joblib launcher (local processes) and ray launcher (a local Ray instance):
both finish every run of a 2-point sweep into the same results layout.

The Ray sweep runs in the default suite (``make test``): ``ray`` is in the ``dev`` extra and the Makefile
installs ``hydra-ray-launcher`` (without its AWS-only boto3 requirement) with it. It starts a local Ray
instance bounded to 2 CPUs, without the dashboard. The joblib sweep stays ``slow`` (it checks the same
layout through processes the suite already exercises)."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys

import pytest

from probeplace.experiment import iter_runs, load_runs

from ._util import ROOT

SWEEP = ["bake=none", "eval=none", "placer.budget=2", "progress=false", "seed=0,1"]


def _run_sweep(tmp_path, launcher: list[str], timeout: float = 900) -> subprocess.CompletedProcess:
    # no usage-statistics prompt or upload from Ray; a sweep that hangs fails at the timeout
    env = dict(os.environ, JAX_PLATFORMS="cpu", RAY_USAGE_STATS_ENABLED="0")
    cmd = [sys.executable, str(ROOT / "experiments" / "run.py"), "--multirun", *launcher]
    cmd += [f"results_dir={tmp_path}", "name=launch", *SWEEP]
    return subprocess.run(cmd, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=timeout)


def _need(module: str, why: str) -> None:
    """Skip, saying why, when ``module`` is not installed (found without importing it here)."""
    try:
        found = importlib.util.find_spec(module) is not None
    except ModuleNotFoundError:
        found = False
    if not found:
        pytest.skip(f"{module} is not installed: {why}")


def _check(tmp_path, proc):
    assert proc.returncode == 0, proc.stdout + proc.stderr
    runs = [p.name for p in iter_runs(tmp_path / "launch")]
    assert runs == [f"cornell_box__skeleton__b2__s{k}" for k in (0, 1)]
    assert all(r["n_probes"] <= 2 and r["coverage"] > 0 for r in load_runs(tmp_path / "launch"))


@pytest.mark.slow
def test_joblib_launcher(tmp_path):
    pytest.importorskip("hydra_plugins.hydra_joblib_launcher")
    _check(tmp_path, _run_sweep(tmp_path, ["hydra/launcher=joblib", "hydra.launcher.n_jobs=2"]))


RAY_SETUP = "the test set-up installs it (`make test`: pyproject's dev extra and the Makefile's stamp rule)"


def test_ray_launcher_local_instance(tmp_path):
    """Two runs on a local Ray instance (2 CPUs, no dashboard), each in a Ray worker process; bounded by
    a timeout well above its measured time (~60 s on 2 shared cores)."""
    _need("ray", RAY_SETUP)
    _need("hydra_plugins.hydra_ray_launcher", RAY_SETUP)
    # address=null: the launcher calls ray.init(**init) and starts a local Ray instance for the sweep
    init = ["+hydra.launcher.ray.init.num_cpus=2", "+hydra.launcher.ray.init.include_dashboard=false"]
    proc = _run_sweep(tmp_path, ["hydra/launcher=ray", *init], timeout=300)
    _check(tmp_path, proc)
    assert "Started a local Ray instance" in proc.stdout + proc.stderr
