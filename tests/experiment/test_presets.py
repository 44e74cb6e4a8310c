"""Every preset runs end to end with a tiny override into tmp_path, and the report is drawn from it."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from probeplace._core import ConfigError, load_probe_set
from probeplace.experiment import is_complete, make_report, run, to_config
from probeplace.render import resolve_backend

from ._util import PRESETS, compose, first_point

# Small enough to run in seconds, large enough for every stage to do real work.
TINY = [
    "placer.budget=2",
    "placer.n_opt_samples=200",
    "bake.radiance_res=4",
    "bake.spp=1",
    "bake.n_sub=1",
    "bake.geometry_res=null",  # sponza_comparison's 512² geometry maps are not tiny
    "bake.backend=jax",  # the presets' Mitsuba backends need its LLVM variant: tests/render covers them
    "eval.backend=jax",
    "eval.width=8",
    "eval.height=8",
    "eval.glossy_spp=1",
    "eval.glossy_ref_spp=2",
    "eval.timing_repeats=1",
    "tracer.spp=2",
    "tracer.max_depth=3",
    "progress=false",
]


def _tiny_run(preset: str, tmp_path, extra: list[str] = ()):
    """The preset's first sweep point (skeleton placement: cheap and always available), tiny sizes."""
    point = first_point(preset)
    cfg = to_config(
        compose(
            [f"+experiment={preset}", *point, "method=skeleton", *TINY, f"results_dir={tmp_path}", *extra]
        )
    )
    return cfg, run(cfg)


def _check_run(cfg, res):
    d = res.out_dir
    assert d.parent.name == cfg.name == res.metrics["experiment"] and is_complete(d)
    names = {p.name for p in d.iterdir()}
    assert {"config.yaml", "metrics.json", "env.json", "probes.json", "top_view.png", "DONE"} <= names
    m = json.loads((d / "metrics.json").read_text())
    assert m == json.loads(json.dumps(res.metrics))
    # the resolved config round-trips to the config that ran
    from omegaconf import OmegaConf

    assert to_config(OmegaConf.load(d / "config.yaml")) == cfg
    env = json.loads((d / "env.json").read_text())
    assert {"python", "jax", "numpy", "git", "device"} <= set(env)
    probes, _ = load_probe_set(d / "probes.json")
    assert probes.n_active == m["n_probes"] <= 2
    assert m["timings"]["place_s"] > 0
    # each probe's part in the coverage, beside probes.json (the viewer reads it without JAX)
    with np.load(d / "probes.coverage.npz") as z:
        assert str(z["format"]) == "probeplace.CoverageDetail/1"
        assert z["seen"].shape == z["unique"].shape == (m["n_probes"],)
        assert float(z["coverage"]) == m["coverage"]
        assert z["unique"].sum() + int(z["n_multiple"]) + len(z["uncovered"]) == int(z["n_coverable"])
        assert z["uncovered_pos"].shape == (len(z["uncovered"]), 3)
    meta = json.loads((d / "probes.json").read_text())["metadata"]
    assert {"relocated_probes", "projected_probes", "filled_probes"} <= set(meta)
    for stage in ("place", "bake", "eval"):
        _check_split(m["timings"], stage, present=stage == "place" or getattr(cfg, stage).enabled)
    if cfg.bake.enabled:
        assert m["timings"]["place_bake_run_s"] == pytest.approx(
            m["timings"]["place_run_s"] + m["timings"]["bake_run_s"], rel=1e-12
        )
        assert m["bake_settings"]["backend"] == resolve_backend(cfg.bake.backend)  # "auto" resolved
        assert m["bake_settings"]["geometry_res"] == (cfg.bake.geometry_res or cfg.bake.radiance_res)
        assert "probes_baked.npz" in names
        with np.load(d / "probes_baked.npz") as z:
            # padded with inactive rows to a power-of-two capacity; the active rows are the placed probes
            cap = len(z["pos_world"])
            assert cap >= 8 and cap & (cap - 1) == 0 and z["active"].sum() == m["n_probes"]
            assert np.allclose(z["pos_world"][z["active"]], probes.pos_world)
    else:
        assert "probes_baked.npz" not in names
    if cfg.eval.enabled:
        ev = m["eval"]
        assert ev["width"] == 8 and np.isfinite(ev["mse_glossy_indirect"])
        assert ev["backend"] == cfg.eval.backend
        assert (d / "eval" / "images.exr").is_file()
        with np.load(d / "eval" / "probe_error.npz") as z:  # each probe's share of the error
            total = z["diffuse_indirect"].sum() + z["unattributed_diffuse_indirect"]
            assert total == pytest.approx(ev["mse_diffuse_indirect"], rel=1e-9)
    return m


def _check_split(t: dict, stage: str, *, present: bool) -> None:
    """``<stage>_compile_s + <stage>_run_s == <stage>_s`` (run is wall − compile, so only rounding
    differs), both parts non-negative; absent for a stage that did not run."""
    keys = [f"{stage}_s", f"{stage}_compile_s", f"{stage}_run_s"]
    if not present:
        assert not set(keys) & set(t)
        return
    wall, comp, run_ = (t[k] for k in keys)
    assert comp >= 0 and run_ >= 0 and comp <= wall
    assert comp + run_ == pytest.approx(wall, rel=1e-9, abs=1e-9)


# Sponza: the slow test below; equal_count_small (a temple run, ~80 s on 2 cores): slow too.
FAST = [p for p in PRESETS if "sponza" not in p and p != "equal_count_small"]


@pytest.mark.parametrize(
    ("preset", "evaluate"),
    [(p, False) for p in FAST]
    + [pytest.param("equal_count_small", False, marks=pytest.mark.slow)]
    + [pytest.param("cornell_comparison", True, marks=pytest.mark.slow)],
    ids=[*FAST, "equal_count_small", "cornell_comparison-eval"],
)
def test_preset_runs_tiny(preset, evaluate, tmp_path):
    """Default run: the presets without the evaluation (its compile dominates: ~1-4 min on 2 cores;
    tests/evaluate covers it); slow: with it, and the report's charts from the real run."""
    # `make demo`'s bake keeps its "auto" backend (TINY sets jax): resolved once, recorded resolved
    demo = ["bake.backend=auto"] if preset == "cornell_comparison" else []
    cfg, res = _tiny_run(preset, tmp_path, ([] if evaluate else ["eval=none"]) + demo)
    m = _check_run(cfg, res)
    if preset == "stability":
        assert not cfg.bake.enabled and cfg.scene.name == "rooms"
        assert isinstance(m["failures"], list)
    if preset == "cornell_comparison":
        assert cfg.bake.backend == "auto" and m["bake_settings"]["backend"] == resolve_backend("auto")
        preset_cfg = to_config(compose(["+experiment=cornell_comparison", "method=skeleton"]))
        assert preset_cfg.bake.backend == preset_cfg.eval.backend == "auto"
    # a second call finds the run finished and does nothing
    again = run(dataclasses.replace(cfg, progress=True))
    assert again.skipped and again.out_dir == res.out_dir
    # ... but not when the same run name would now mean other settings
    other = dataclasses.replace(cfg, placer=dataclasses.replace(cfg.placer, target=0.9))
    with pytest.raises(ConfigError, match=r"different config \(placer\.target differ\)"):
        run(other)
    report = make_report(res.out_dir.parent)
    text = report.read_text()
    assert res.out_dir.name in text
    pngs = {p.name for p in report.parent.glob("*.png")}
    if cfg.eval.enabled:
        assert {"mse_vs_count.png", "mse_vs_time.png", "memory_vs_mse.png", "error_images.png"} <= pngs
    assert (report.parent / "top_views" / f"{res.out_dir.name}.png").is_file()


# ~60 s even without evaluation (Sponza's SDF and caster): slow; Sponza stays in the default run through
# the tracer identity test (tests/probes/test_wavefront.py) and the bake's inside test.
@pytest.mark.slow
@pytest.mark.parametrize("evaluate", [False, True], ids=["", "eval"])
def test_sponza_preset_runs_tiny(evaluate, tmp_path, monkeypatch):
    """Sponza from the shared scenes (skipped with the reason where they are absent); the default run
    without the evaluation, like the other presets."""
    from probeplace.scene import SCENE_PATH_ENV

    from ..helpers import shared_scene_path

    monkeypatch.setenv(SCENE_PATH_ENV, str(shared_scene_path("crytek_sponza.glb").parent))
    cfg, res = _tiny_run("sponza_comparison", tmp_path, [] if evaluate else ["eval=none"])
    m = _check_run(cfg, res)
    assert cfg.scene.name == "crytek_sponza" and m["n_probes"] >= 1


@pytest.mark.slow  # a second tiny run; the backend keys are checked by test_config, Mitsuba by tests/render
def test_mitsuba_bake_runs_tiny(tmp_path):
    """bake.backend=mitsuba with a finer geometry map: the backend and geometry resolution reach the bake
    and metrics.json, and Dr.Jit's compile time is split off like JAX's."""
    try:
        from probeplace.render._mitsuba_backend import load_mitsuba

        load_mitsuba()
    except ImportError as e:
        pytest.skip(f"Mitsuba's LLVM variant cannot load here: {e}")
    extra = ["eval=none", "bake.backend=mitsuba", "bake.geometry_res=8"]
    cfg, res = _tiny_run("cornell_comparison", tmp_path, extra)
    assert (cfg.bake.backend, cfg.bake.geometry_res, cfg.bake.radiance_res) == ("mitsuba", 8, 4)
    m = _check_run(cfg, res)
    assert m["bake_settings"]["backend"] == "mitsuba" and m["bake_settings"]["geometry_res"] == 8
    with np.load(res.out_dir / "probes_baked.npz") as z:
        assert z["distance"].shape[-1] == 8 + 2 and z["radiance"].shape[-2] == 4 + 2  # one-texel border
