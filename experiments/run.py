"""Hydra entry point: one run, or a sweep with ``--multirun`` (basic, joblib or ray launcher).

    python experiments/run.py                                   # one run, configs/config.yaml
    python experiments/run.py +experiment=cornell_comparison    # a preset (configs/experiment/), sweeps
    python experiments/run.py --multirun scene=cornell_box,rooms method=grid,skeleton_gibbs \
        placer.budget=auto,16 seed=0,1 hydra/launcher=joblib hydra.launcher.n_jobs=2
    python experiments/run.py --multirun method=grid,skeleton hydra/launcher=ray   # local Ray instance

Every run goes to ``results/<experiment>/<run>/`` (written atomically); a re-run of a sweep skips the
finished runs and redoes an interrupted one. The work itself is ``probeplace.experiment.run``.

This file is the only place Hydra and OmegaConf meet the library: it stores the schema
(``probeplace.experiment.ExperimentConfig``) in Hydra's ConfigStore as ``base_config`` (configs/config.yaml
lists it first, so every group merges onto a typed node and unknown keys or wrong types are refused at
composition) and hands ``run`` the typed config.
"""

from __future__ import annotations

import signal
import sys
from pathlib import Path

import hydra
from hydra.core.config_store import ConfigStore
from omegaconf import DictConfig, OmegaConf

from probeplace._core import ProbeplaceError
from probeplace.experiment import ExperimentConfig, run

CONFIG_DIR = str(Path(__file__).resolve().parents[1] / "configs")


def register_configs() -> None:
    """Store the schema in Hydra's ConfigStore as ``base_config``."""
    ConfigStore.instance().store(name="base_config", node=ExperimentConfig)


register_configs()


def _sigterm(signum, frame):  # a terminated sweep unwinds like Ctrl-C: the partial folder is removed
    raise KeyboardInterrupt(f"signal {signum}")


@hydra.main(version_base="1.3", config_path=CONFIG_DIR, config_name="config")
def main(cfg: DictConfig) -> dict:
    signal.signal(signal.SIGTERM, _sigterm)
    try:
        result = run(OmegaConf.to_object(cfg))
    except ProbeplaceError as e:  # one clear line per failed run, no traceback
        print(f"probeplace: error: {e}", file=sys.stderr)
        raise SystemExit(2) from None
    state = "skipped (finished)" if result.skipped else "done"
    print(f"{result.out_dir}: {state}", flush=True)
    return {"out_dir": str(result.out_dir), "skipped": result.skipped}


if __name__ == "__main__":
    main()
