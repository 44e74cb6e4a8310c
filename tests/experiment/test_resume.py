"""Kill a sweep mid-run (SIGTERM, then SIGKILL) and resume it: finished runs are kept untouched, the
interrupted run is redone, and no partial folder is ever read as complete (issue 9)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from probeplace.experiment import is_complete, iter_runs, load_runs

from ._util import ROOT

CHILD = Path(__file__).with_name("_sweep_child.py")
RUNS = [f"cornell_box__skeleton__b2__s{k}" for k in range(3)]


def _sweep(tmp: Path, stall: str | None) -> subprocess.Popen:
    env = dict(os.environ)
    env.update(
        JAX_PLATFORMS="cpu",
        JAX_COMPILATION_CACHE_DIR=str(tmp / "jax_cache"),  # the 2nd and 3rd sweeps reuse compilations
        JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0",
        STALL_FLAG=str(tmp / "stalled"),
        STALL_RUN=stall or "",
        PYTHONPATH=str(ROOT),
    )
    (tmp / "stalled").unlink(missing_ok=True)
    log = tmp / "sweep.log"
    args = [
        "--multirun",
        f"results_dir={tmp / 'results'}",
        "name=resume",
        "bake=none",
        "eval=none",
        "placer.budget=2",
        "progress=false",
        "seed=0,1,2",
    ]
    with open(log, "w") as f:  # the child holds its own copy of the descriptor
        return subprocess.Popen(
            [sys.executable, str(CHILD), *args], env=env, cwd=tmp, stdout=f, stderr=subprocess.STDOUT
        )


def _log(tmp: Path) -> str:
    return (tmp / "sweep.log").read_text()


def _wait_stalled(proc: subprocess.Popen, tmp: Path, timeout: float = 300.0) -> Path:
    t0 = time.monotonic()
    while not (tmp / "stalled").exists():
        assert proc.poll() is None, f"sweep ended before the stall:\n{_log(tmp)}"
        assert time.monotonic() - t0 < timeout, "sweep did not reach the stalled run"
        time.sleep(0.2)
    time.sleep(0.2)  # the flag is written after the work, before the commit
    return Path((tmp / "stalled").read_text())


def _stamp(d: Path) -> dict:
    return {p.name: p.stat().st_mtime_ns for p in [d, *d.iterdir()]}


def test_killed_sweep_resumes(tmp_path):
    exp = tmp_path / "results" / "resume"
    done0 = exp / RUNS[0]

    # 1. SIGTERM while run s1 is in progress: s0 finished, s1 never appears as a run, its partial is removed
    proc = _sweep(tmp_path, stall=RUNS[1])
    partial = _wait_stalled(proc, tmp_path)
    assert partial.parent == exp and partial.name.startswith(f".{RUNS[1]}.partial")
    assert (partial / "metrics.json").is_file() and not is_complete(partial)
    assert is_complete(done0) and not (exp / RUNS[1]).exists()
    assert [r["run"] for r in load_runs(exp)] == [RUNS[0]]
    stamp0 = _stamp(done0)
    proc.send_signal(signal.SIGTERM)
    proc.wait(timeout=60)
    assert proc.returncode != 0
    assert not partial.exists(), "SIGTERM: the interrupted run's partial folder is cleaned up"
    assert [p.name for p in iter_runs(exp)] == [RUNS[0]]

    # 2. re-run, SIGKILL at the same point: s0 skipped (untouched), a stale partial folder is left behind
    proc = _sweep(tmp_path, stall=RUNS[1])
    partial = _wait_stalled(proc, tmp_path)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=60)
    assert partial.is_dir() and not is_complete(partial)
    assert not (exp / RUNS[1]).exists() and not (exp / RUNS[2]).exists()
    assert [p.name for p in iter_runs(exp)] == [RUNS[0]], "a partial folder is never read as complete"
    assert _stamp(done0) == stamp0

    # 3. resume to the end: s0 untouched, s1 redone, s2 done, no partial folder remains
    proc = _sweep(tmp_path, stall=None)
    proc.wait(timeout=600)
    out = _log(tmp_path)
    assert proc.returncode == 0, out
    assert f"{RUNS[0]}: skipped (finished)" in out
    assert _stamp(done0) == stamp0
    assert [p.name for p in iter_runs(exp)] == RUNS
    assert not list(exp.glob(".*.partial*"))
    for name in RUNS:
        assert {"config.yaml", "metrics.json", "env.json", "probes.json", "DONE"} <= {
            p.name for p in (exp / name).iterdir()
        }
