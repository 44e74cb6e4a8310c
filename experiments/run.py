"""Hydra entry point: one run, or a sweep with ``--multirun`` (basic, joblib or ray launcher).

    python experiments/run.py                                   # one run, configs/config.yaml
    python experiments/run.py +experiment=cornell_comparison    # a preset (configs/experiment/), sweeps
    python experiments/run.py --multirun scene=cornell_box,rooms method=grid,skeleton_gibbs \
        placer.budget=auto,16 seed=0,1 hydra/launcher=joblib hydra.launcher.n_jobs=2
    python experiments/run.py --multirun method=grid,skeleton hydra/launcher=ray   # local Ray instance

Every run goes to ``results/<experiment>/<run>/`` (written atomically); a re-run of a sweep skips the
finished runs that ran with the same config and inputs, refuses those whose config or inputs changed
(``redo=stale`` redoes them, ``redo=all`` every run) and redoes an interrupted one. The work itself is
``probeplace.experiment.run``.

This file is the only place Hydra and OmegaConf meet the library: it stores the schema
(``probeplace.experiment.ExperimentConfig``) in Hydra's ConfigStore as ``base_config`` (configs/config.yaml
lists it first, so every group merges onto a typed node and unknown keys or wrong types are refused at
composition) and hands ``run`` the composed config as a plain dict (``run`` types and validates it), so
that a key added with ``+key=...``, which Hydra lets through, is refused too.

Before Hydra starts, :func:`_precheck` composes every run the command line asks for (each swept value
once) and validates it: an unknown key, a bad value, Hydra's own errors (a misspelt key, a wrong type, a
missing option), a bake or image too large for memory and an unwritable results folder are one line
``probeplace: error: ...`` and exit status 2, like the ``probeplace`` command's. It then loads each scene
once (``probeplace.experiment.check_scenes``): a scene that cannot be loaded, one with no light for a run
that bakes, and an ``eval.view`` the scene lacks are refused the same way, before any run starts; so is a
finished run whose config or inputs (scene file hash, resolved sidecar, code version) differ from the
command's (``check_finished``; ``redo=stale`` redoes it instead). ``scene=<file>`` (a config option that
does not exist) is answered with the ``scene.name=<file>`` form.
Ctrl-C is one line ``probeplace: interrupted`` and status 130 (the interrupted run's partial folder is
removed).
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import signal
import sys
from pathlib import Path
from typing import NoReturn

import hydra
from hydra.core.config_store import ConfigStore
from omegaconf import DictConfig, OmegaConf

from probeplace._core import ProbeplaceError
from probeplace._core.runtime import enable_compilation_cache
from probeplace.experiment import ExperimentConfig, run

enable_compilation_cache()  # JAX's compilation cache (issue 32: $PROBEPLACE_JAX_CACHE), before any compile

CONFIG_DIR = str(Path(__file__).resolve().parents[1] / "configs")


def register_configs() -> None:
    """Store the schema in Hydra's ConfigStore as ``base_config``."""
    ConfigStore.instance().store(name="base_config", node=ExperimentConfig)


register_configs()


def _sigterm(signum, frame):  # a terminated sweep unwinds like Ctrl-C: the partial folder is removed
    raise KeyboardInterrupt(f"signal {signum}")


def _fail(message: str) -> NoReturn:
    """The runner's errors read like the CLI's: one line, exit status 2."""
    print(f"probeplace: error: {' '.join(message.split())}", file=sys.stderr, flush=True)
    raise SystemExit(2)


@hydra.main(version_base="1.3", config_path=CONFIG_DIR, config_name="config")
def main(cfg: DictConfig) -> dict:
    signal.signal(signal.SIGTERM, _sigterm)
    try:
        # a plain dict, so that the schema sees every key: an added one (``+colour=red``) is refused
        result = run(OmegaConf.to_container(cfg, resolve=True))
    except ProbeplaceError as e:  # one clear line per failed run, no traceback
        _fail(str(e))
    except OSError as e:  # results folder not writable, disk full, ...
        _fail(f"{e.strerror}: {e.filename}" if e.filename is not None and e.strerror else str(e))
    state = "skipped (finished)" if result.skipped else "done"
    print(f"{result.out_dir}: {state}", flush=True)
    return {"out_dir": str(result.out_dir), "skipped": result.skipped}


# --- checks before Hydra starts: every run of the command line composed and validated ---------------
def _one_line(e: BaseException) -> str:
    """A Hydra / OmegaConf error (and its cause) as one line: OmegaConf's ``full_key:`` / ``object_type=``
    detail lines and Hydra's config search path dropped (the message names the key already), an indented
    list joined by commas."""
    parts: list[str] = []
    for err in (e, e.__cause__):
        for line in str(err or "").splitlines():
            text = line.strip()
            if text.startswith("Config search path"):  # Hydra's internals, after the message proper
                break
            if not text or text.startswith(("full_key:", "object_type=", "reference_type=")) or text in parts:
                continue
            if line.startswith("\t") and parts and not parts[-1].endswith(":"):
                parts[-1] += f", {text}"
            else:
                parts.append(text)
    return " ".join(parts) or type(e).__name__


def _planned_runs(compose, overrides: list[str], multirun: bool) -> list[list[str]]:
    """The overrides of the runs the command line asks for, as Hydra's basic sweeper forms them (the
    config's ``hydra.sweeper.params``, then the command line's, a later key winning): with a sweep, the
    first value of every key, then each further value of one key at a time, so every value is composed
    once (not the whole product)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.types import RunMode

    parser = OverridesParser.create()
    parsed = parser.parse_overrides(overrides)
    plain = [o.input_line for o in parsed if not o.is_sweep_override()]
    head = compose(plain, return_hydra_config=True)
    if not (multirun or head.hydra.mode == RunMode.MULTIRUN):
        return [overrides]  # a sweep here is Hydra's own "ambiguous value" error, composed below
    params = OmegaConf.select(head, "hydra.sweeper.params") or {}
    lines = [f"{k}={v}" for k, v in params.items()] + list(overrides)
    values: dict[str, list[str]] = {}
    for o in parser.parse_overrides(lines):
        key = o.get_key_element()
        if o.is_sweep_override():
            values[key] = [f"{key}={v}" for v in o.sweep_string_iterator()]
        else:
            values[key] = [f"{key}={o.get_value_element_as_str()}"]
    base = [v[0] for v in values.values()]
    runs = [base]
    for i, vs in enumerate(values.values()):
        runs += [[*base[:i], v, *base[i + 1 :]] for v in vs[1:]]
    return runs


def _precheck(argv: list[str]) -> None:
    """Compose and validate every run of the command line before Hydra starts any: unknown keys, bad
    values, missing config options, an unwritable results folder or an image too large for memory are
    one line ``probeplace: error: ...`` and exit status 2, in well under a second per run; then each
    scene is loaded once to check its light and the runs' ``eval.view`` (module docstring). Hydra's own
    modes (``--help``, ``--cfg``, ``--info``, a custom config path) are left to Hydra."""
    from hydra import compose, initialize_config_dir
    from hydra._internal.utils import get_args_parser
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    from probeplace._core.runtime import check_writable_folder
    from probeplace.experiment import check_scenes, to_config
    from probeplace.experiment._run import check_finished

    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            args = get_args_parser().parse_args(argv)
    except SystemExit:  # a bad flag, or --version: Hydra answers it as it always does
        return
    hydra_modes = (args.help, args.hydra_help, args.cfg, args.info, args.shell_completion)
    if any(hydra_modes) or args.config_path or args.config_dir or args.experimental_rerun:
        return
    name = args.config_name or "config"
    try:
        with initialize_config_dir(config_dir=CONFIG_DIR, version_base="1.3"):

            def composed(overrides, return_hydra_config=False):
                return compose(name, overrides=overrides, return_hydra_config=return_hydra_config)

            cfgs = []
            for overrides in _planned_runs(composed, args.overrides, args.multirun):
                cfg = to_config(OmegaConf.to_container(composed(overrides), resolve=True))
                check_writable_folder(Path(cfg.results_dir) / cfg.name, "results_dir")
                cfgs.append(cfg)
        # each scene loaded once: light for a bake, the eval.view of every run (before the first starts)
        check_scenes(cfgs)
        # a finished run met again with other inputs (a changed sidecar sun, scene file or code version)
        check_finished(cfgs)
    except (HydraException, OmegaConfBaseException) as e:
        _fail(_scene_hint(_one_line(e)))
    except ProbeplaceError as e:
        _fail(str(e))


def _scene_hint(message: str) -> str:
    """Hydra's "Could not find 'scene/<name>'" with the form a scene file takes: ``scene=`` picks a
    config option (configs/scene/), while a scene file or a scene on the search path is ``scene.name=``."""
    m = re.search(r"Could not find 'scene/(.+?)'", message)
    if m is None:
        return message
    return (
        f"{message.rstrip('. ')}; scene=<option> picks one of configs/scene/: a scene file, or a scene "
        f"on the search path, is given as scene.name={m.group(1)} (docs/scenes.md)"
    )


if __name__ == "__main__":
    from probeplace._core.runtime import interruptible

    try:
        with interruptible():
            _precheck(sys.argv[1:])
            main()
    except KeyboardInterrupt:  # the run removed its partial folder; no traceback
        print("probeplace: interrupted", file=sys.stderr, flush=True)
        sys.stdout.flush()
        os._exit(130)  # not sys.exit: interpreter shutdown with XLA threads cut short can segfault
