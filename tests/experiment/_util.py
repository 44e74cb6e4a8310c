"""Shared helpers of the experiment tests: Hydra composition of configs/ without running Hydra's app."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = ROOT / "configs"
PRESETS = sorted(p.stem for p in (CONFIGS / "experiment").glob("*.yaml"))


def experiment_script(name: str):
    """experiments/``name``.py loaded as a module (the experiments are scripts, not a package)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, ROOT / "experiments" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def benchmark_module(name: str):
    """benchmarks/``name``.py imported by name, as the experiments import it (they put benchmarks/ on
    ``sys.path``): the one module object they use, so a test's monkeypatch reaches them."""
    import importlib
    import sys

    if str(ROOT / "benchmarks") not in sys.path:
        sys.path.insert(0, str(ROOT / "benchmarks"))
    return importlib.import_module(name)


def compose(overrides: list[str], *, hydra_cfg: bool = False):
    """The config experiments/run.py would get for ``overrides`` (with ``hydra`` when ``hydra_cfg``)."""
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.core.config_store import ConfigStore
    from hydra.core.global_hydra import GlobalHydra

    from probeplace.experiment import ExperimentConfig

    if not GlobalHydra.instance().is_initialized():  # once per process: initialising is the slow part
        # what experiments/run.py's register_configs does (the Hydra edge; the library has no Hydra)
        ConfigStore.instance().store(name="base_config", node=ExperimentConfig)
        initialize_config_dir(config_dir=str(CONFIGS), version_base="1.3").__enter__()
    return hydra_compose("config", overrides=overrides, return_hydra_config=hydra_cfg)


def sweep_params(preset: str) -> dict[str, list[str]]:
    """The preset's ``hydra.sweeper.params``, each expanded to its list of override strings."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    cfg = compose([f"+experiment={preset}"], hydra_cfg=True)
    parser = OverridesParser.create()
    out = {}
    for key, value in cfg.hydra.sweeper.params.items():
        (ov,) = parser.parse_overrides([f"{key}={value}"])
        out[key] = (
            list(ov.sweep_string_iterator()) if ov.is_sweep_override() else [ov.get_value_element_as_str()]
        )
    return out


def first_point(preset: str) -> list[str]:
    """The overrides of the preset's first sweep point but its method (the tests choose their own)."""
    return [f"{k}={v[0]}" for k, v in sweep_params(preset).items() if k != "method"]
