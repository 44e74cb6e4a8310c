"""Child process of test_resume: experiments/run.py, with one run made to stall before it commits.

With STALL_RUN=<run name>, that run does all its work into its partial folder, then writes the partial
folder's path to STALL_FLAG and sleeps, so the test can kill the sweep at a known point mid-run.
"""

from __future__ import annotations

import os
import runpy
import sys
import time
from pathlib import Path

import probeplace.experiment._run as _run

ROOT = Path(__file__).resolve().parents[2]
_original = _run._execute


def _stalling_execute(cfg, partial, final):
    metrics = _original(cfg, partial, final)
    if final.name == os.environ.get("STALL_RUN"):
        Path(os.environ["STALL_FLAG"]).write_text(str(partial))
        time.sleep(600)
    return metrics


_run._execute = _stalling_execute
sys.argv = [str(ROOT / "experiments" / "run.py"), *sys.argv[1:]]
runpy.run_path(sys.argv[0], run_name="__main__")
