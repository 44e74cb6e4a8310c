"""The library's experiment package works without Hydra or OmegaConf: they stay in experiments/run.py."""

from __future__ import annotations

import json
import subprocess
import sys

from ._util import ROOT

_CHILD = """
import json, sys
import probeplace.experiment as ex
from probeplace.experiment import (
    ExperimentConfig, RunResult, load_runs, make_report, pareto_front, run, run_dir, run_name, to_config,
)
from probeplace.experiment._report import _top_views
from probeplace.experiment._run import _check_same_config, _execute
from probeplace.experiment._schema import config_to_yaml, load_config_yaml

cfg = to_config({"placer": {"method": "grid", "budget": 8, "options": {"jitter": 0.5}}, "seed": 2})
text = config_to_yaml(cfg)
run_name(cfg)
print(json.dumps({m: m in sys.modules for m in ("hydra", "omegaconf")}))
"""


def test_experiment_package_imports_without_hydra_or_omegaconf():
    out = subprocess.run(
        [sys.executable, "-c", _CHILD], cwd=ROOT, capture_output=True, text=True, check=True, timeout=600
    )
    assert json.loads(out.stdout.strip().splitlines()[-1]) == {"hydra": False, "omegaconf": False}


def test_no_module_under_src_imports_hydra_or_omegaconf():
    """Not even lazily, inside a function: the library is called from pytest, Ray Tune or a notebook."""
    import re

    pattern = re.compile(r"^\s*(from|import)\s+(hydra|omegaconf)\b", re.M)
    offenders = [
        str(p.relative_to(ROOT)) for p in (ROOT / "src").rglob("*.py") if pattern.search(p.read_text())
    ]
    assert offenders == []
