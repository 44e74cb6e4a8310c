"""Config schema: Hydra composition of every group and preset; invalid values and unknown keys are
rejected with a ConfigError that names the key."""

from __future__ import annotations

import re

import pytest

from probeplace._core import ConfigError
from probeplace.experiment import ExperimentConfig, run, run_name, to_config
from probeplace.placement import get_method, method_names
from probeplace.render import BACKEND_CHOICES

from ._util import CONFIGS, PRESETS, compose, sweep_params


def test_default_config_composes_to_schema_defaults():
    cfg = to_config(compose([]))
    assert isinstance(cfg, ExperimentConfig)
    # configs/ group defaults restate the schema defaults: composing them changes nothing
    assert cfg == to_config({})


@pytest.mark.parametrize(
    "group", ["scene", "placer", "refiner", "bake", "tracer", "eval", "export", "method"]
)
def test_every_group_option_composes_and_validates(group):
    for option in sorted(p.stem for p in (CONFIGS / group).glob("*.yaml")):
        extra = ["eval=none"] if (group, option) == ("bake", "none") else []  # eval needs a bake
        cfg = to_config(compose([f"{group}={option}", *extra]))
        if group == "placer":
            assert get_method(cfg.placer.method).config_name == option
        if group == "refiner":
            assert cfg.refiner.name == option


#: Presets that write into another experiment's folder (its report shows both).
WRITES_INTO = {"cornell_own_counts": "cornell_comparison"}  # make demo's second sweep


@pytest.mark.parametrize("preset", PRESETS)
def test_every_swept_value_of_a_preset_validates(preset):
    params = sweep_params(preset)
    assert params, f"{preset} sweeps nothing"
    for key, values in params.items():
        for v in values:
            cfg = to_config(compose([f"+experiment={preset}", f"{key}={v}"]))
            assert cfg.name == WRITES_INTO.get(preset, preset)


def test_placer_configs_are_the_registered_methods():
    """One config per registered placement method, named by its ``config_name``, and no other."""
    files = {p.stem for p in (CONFIGS / "placer").glob("*.yaml")}
    assert files == {get_method(m).config_name for m in method_names()}


def test_bake_and_eval_groups_are_built_from_the_library_configs():
    """Every scalar library setting is a key of its group, with the library's default unless the runner
    sets it itself; the library config of a run carries the group's values."""
    import dataclasses

    from probeplace.evaluate import EvalConfig
    from probeplace.experiment import BakeStage, EvalStage, bake_config, eval_config
    from probeplace.probes import BakeConfig

    bake_keys = {f.name for f in dataclasses.fields(BakeStage)}
    assert {"irradiance_res", "moments_res", "inside_test", "quality"} <= bake_keys
    assert "progress" not in bake_keys and "max_depth" not in bake_keys
    eval_keys = {f.name for f in dataclasses.fields(EvalStage)}
    assert {"glossy_filter", "normal_bias", "bootstrap_resamples"} <= eval_keys
    assert not {"spp", "max_depth", "seed", "progress", "trace"} & eval_keys
    cfg = to_config({"bake": {"moments_res": 8}, "eval": {"glossy_filter": "bilinear"}, "tracer": {"spp": 3}})
    assert bake_config(cfg) == BakeConfig(radiance_res=16, moments_res=8, probes_per_batch=4, progress=True)
    ev = eval_config(cfg)
    assert isinstance(ev, EvalConfig) and (ev.glossy_filter, ev.spp, ev.max_depth) == ("bilinear", 3, 4)
    # the same keys as Hydra overrides
    composed = to_config(compose(["bake.moments_res=8", "eval.glossy_filter=bilinear", "tracer.spp=3"]))
    assert composed == cfg


def test_presets_cover_the_issue():
    from probeplace.placement import REFINERS

    from ._util import CONFIGS

    # make demo: the baselines, Wang's Gibbs sampler and a gradient refiner at the grid's count, 3 seeds,
    # and the same methods at their own automatic counts; every refiner has its method config
    cornell = sweep_params("cornell_comparison")
    assert {"grid", "lod_grid_64", "skeleton", "vardis", "skeleton_gibbs"} <= set(cornell["method"])
    assert any(f"skeleton_{r}" in cornell["method"] for r in REFINERS if r not in ("gibbs", "ascent"))
    assert cornell["placer.budget"] == ["27"] and len(cornell["seed"]) >= 3
    own = sweep_params("cornell_own_counts")
    assert own["placer.budget"] == ["auto"] and set(own["method"]) <= set(cornell["method"])
    assert all((CONFIGS / "method" / f"skeleton_{r}.yaml").is_file() for r in REFINERS)
    stab = sweep_params("stability")
    assert set(stab["scene"]) == {"rooms", "temple", "courtyard"}
    assert len(stab["seed"]) >= 10
    assert len(stab["scene.translate_frac"]) >= 2 and len(stab["scene.rotate_deg"]) >= 2


BAD = [
    ({"placer": {"budget": -3}}, "placer.budget: must be 'auto' or a positive integer, got -3"),
    ({"placer": {"budget": "lots"}}, "placer.budget"),
    ({"placer": {"method": "random"}}, "placer.method"),
    ({"placer": {"target": 0.0}}, "placer.target"),
    ({"placer": {"n_opt_samples": "many"}}, "placer.n_opt_samples"),
    ({"placer": {"coverage": "everything"}}, "placer.coverage: must be one of"),
    ({"placer": {"memory_budget": "12 parsecs"}}, "placer.memory_budget: memory budget must be"),
    ({"placer": {"memory_budget": "64MiB", "budget": 8}}, "placer.budget: must be 'auto' when"),
    ({"placer": {"clearance": -1.0}}, "placer.clearance"),
    ({"placer": {"region": {"height": [2.0, 1.0]}}}, "placer.region.height"),
    ({"placer": {"region": {"boxes": 3}}}, "placer.region.boxes"),
    ({"refiner": {"name": "newton"}}, "refiner.name"),
    ({"placer": {"method": "grid", "options": {"spacing": 3}}}, "placer.options.spacing"),
    ({"placer": {"method": "skeleton", "options": {"jitter": 0.5}}}, "placer.options.jitter"),
    ({"bake": {"radiance_res": 12}}, "bake.radiance_res: must be a power of two"),
    ({"bake": {"geometry_res": 48}}, "bake.geometry_res: must be a power of two >= 2, got 48"),
    ({"bake": {"geometry_res": 1}}, "bake.geometry_res: must be >= 2 or None, got 1"),
    ({"bake": {"backend": "embree"}}, f"bake.backend: must be one of {BACKEND_CHOICES}, got 'embree'"),
    ({"eval": {"backend": "cuda"}}, f"eval.backend: must be one of {BACKEND_CHOICES}, got 'cuda'"),
    ({"bake": {"spp": 0}}, "bake.spp"),
    ({"tracer": {"max_depth": 2}}, "tracer.max_depth"),
    ({"eval": {"shading": "phong"}}, "eval.shading"),
    ({"eval": {"glossy_ref_spp": 1}}, "eval.glossy_ref_spp"),
    ({"bake": {"n_sub": 0}}, "bake.n_sub: must be >= 1, got 0"),
    ({"bake": {"inside_test": "ask"}}, "bake.inside_test: must be one of"),
    ({"eval": {"glossy_filter": "blur"}}, "eval.glossy_filter: must be one of"),
    (
        {"eval": {"trace_engine": "fast"}},
        "eval.trace_engine: must be one of ('per_ray', 'wavefront'), got 'fast'",
    ),
    ({"bake": {"enabled": False}}, "eval.enabled"),
    ({"export": {"formats": ["fbx"]}}, "export.formats[0]"),
    ({"scene": {"translate_frac": [1.0, 0.0, 0.0]}}, "scene.translate_frac"),
    ({"scene": {"rotate_deg": 400.0}}, "scene.rotate_deg"),
    ({"seed": -1}, "seed"),
    ({"name": "../escape"}, "name"),
    # unknown keys (struct mode) and wrong types, at any depth
    ({"placer": {"buget": 3}}, "placer.buget"),
    ({"bake": {"res": 8}}, "bake.res"),
    ({"colour": "red"}, "colour"),
    ({"eval": {"width": "wide"}}, "eval.width"),
    # issue 33: counts chosen from a noise target
    ({"tracer": {"spp": "autox"}}, "tracer.spp: must be a positive int or 'auto', got 'autox'"),
    ({"tracer": {"spp": 2.5}}, "tracer.spp: must be an integer or a string, got 2.5"),
    ({"tracer": {"noise_target": 0.0}}, "tracer.noise_target: must be in (0, 1), got 0.0"),
    ({"tracer": {"noise_target": 1.0}}, "tracer.noise_target: must be in (0, 1), got 1.0"),
    ({"tracer": {"pilot_spp": 1}}, "tracer.pilot_spp: must be >= 2, got 1"),
    ({"tracer": {"spp": "auto", "max_spp": 4}}, "tracer.max_spp: must be >= pilot_spp (8)"),
    (
        {"eval": {"glossy_ref_spp": "autox"}},
        "eval.glossy_ref_spp: must be an int >= 2 or 'auto', got 'autox'",
    ),
    ({"bake": {"spp": "autox"}}, "bake.spp: must be a positive int or 'auto', got 'autox'"),
    ({"bake": {"noise_target": -0.1}}, "bake.noise_target: must be in (0, 1), got -0.1"),
    ({"bake": {"max_spp": 0}}, "bake.max_spp: must be >= 1, got 0"),
]


@pytest.mark.parametrize(("override", "key"), BAD, ids=[m for _, m in BAD])
def test_invalid_values_and_unknown_keys_name_the_key(override, key, tmp_path):
    with pytest.raises(ConfigError, match="^" + re.escape(key)):
        to_config(override)
    # run() refuses before any work: nothing is written
    with pytest.raises(ConfigError, match=re.escape(key)):
        run({**override, "results_dir": str(tmp_path)})
    assert not any(tmp_path.iterdir())


def test_counts_take_auto_and_their_targets():
    """Issue 33: ``tracer.spp``, ``eval.glossy_ref_spp`` and ``bake.spp`` take ``auto`` (from a dict and as
    Hydra overrides), numeric text stays a count, and the targets reach the library configs."""
    from probeplace.experiment import bake_config, eval_config

    over = ["tracer.spp=auto", "eval.glossy_ref_spp=auto", "bake.spp=auto", "tracer.noise_target=0.1"]
    over += ["tracer.max_spp=64", "bake.noise_target=0.2", "bake.max_spp=32", "bake.pilot_spp=2"]
    cfg = to_config(compose(over))
    assert (cfg.tracer.spp, cfg.eval.glossy_ref_spp, cfg.bake.spp) == ("auto", "auto", "auto")
    ev, bake = eval_config(cfg), bake_config(cfg)
    assert (ev.spp, ev.glossy_ref_spp, ev.noise_target, ev.max_spp, ev.pilot_spp) == (
        "auto",
        "auto",
        0.1,
        64,
        8,
    )
    assert (bake.noise_target, bake.max_spp, bake.pilot_spp) == (0.2, 32, 2)
    assert to_config({"tracer": {"spp": "32"}, "bake": {"spp": "8"}}).tracer.spp == 32
    assert to_config({"bake": {"spp": "8"}}).bake.spp == 8
    # the defaults stay fixed counts
    d = to_config({})
    assert (d.tracer.spp, d.eval.glossy_ref_spp, d.bake.spp) == (16, 4, 4)


def test_hydra_rejects_unknown_override_naming_it():
    from hydra.errors import ConfigCompositionException

    with pytest.raises(ConfigCompositionException, match=r"placer\.buget"):
        compose(["placer.buget=3"])


def test_run_name_is_unique_per_swept_coordinate():
    names = {
        run_name(to_config({"scene": {"name": s}, "placer": {"method": m, "budget": b}, "seed": k}))
        for s in ("cornell_box", "rooms")
        for m in ("grid", "skeleton")
        for b in ("auto", 8)
        for k in (0, 1)
    }
    assert len(names) == 16
    moved = to_config({"scene": {"translate_frac": [0.01, 0.0, 0.0], "rotate_deg": 2.5}})
    assert run_name(moved) != run_name(to_config({}))
    grid = {"method": "grid", "budget": 8}
    offsets = [[0.0, 0.0, 0.0], [0.25, 0.0, 0.5]]
    swept = {run_name(to_config({"placer": {**grid, "options": {"offset": o}}})) for o in offsets}
    assert len(swept) == 2 and run_name(to_config({"placer": grid})) not in swept
    # a swept refiner objective too (the default keeps the name it always had)
    refined = {"placer": {"method": "skeleton", "objective": "coverage"}, "refiner": {"name": "lbfgsb"}}
    objectives = {
        run_name(to_config({**refined, "placer": {**refined["placer"], "objective": o}}))
        for o in ("coverage", "wang", "shading")
    }
    assert len(objectives) == 3 and run_name(to_config(refined)) in objectives


def test_scene_offset_moves_the_scene_relative_to_the_grid():
    """translate_frac moves the bounds by that fraction of the extent; rotate_deg turns the scene about
    +Y through its bounding-box centre (a quarter turn swaps the x and z extents, keeps the centre)."""
    import numpy as np

    from probeplace.experiment import SceneStage, load_experiment_scene

    base = np.asarray(load_experiment_scene(SceneStage()).bounds, np.float64)
    ext = base[1] - base[0]
    moved = np.asarray(load_experiment_scene(SceneStage(translate_frac=[0.1, -0.05, 0.02])).bounds)
    np.testing.assert_allclose(moved, base + np.array([0.1, -0.05, 0.02]) * ext, rtol=1e-5, atol=1e-3)
    turned = np.asarray(load_experiment_scene(SceneStage(rotate_deg=90.0)).bounds, np.float64)
    np.testing.assert_allclose(turned.mean(0), base.mean(0), atol=1e-3 * ext.max())
    np.testing.assert_allclose((turned[1] - turned[0])[[2, 1, 0]], ext, rtol=1e-5)


def test_unknown_view_is_refused_before_any_work(tmp_path):
    with pytest.raises(ConfigError, match=r"^eval\.view: scene 'cornell_box' has no view 'CameraMain'"):
        run({"eval": {"view": "CameraMain"}, "results_dir": str(tmp_path)})
    assert not [p for p in (tmp_path / "default").iterdir() if not p.name.startswith(".")]


def test_translation_moves_the_scene_relative_to_the_lattice_methods_grid():
    """For a translated scene the lattice methods get ``shift = −translation`` (added to any given shift), so
    their box-anchored grid stays put in the world; the skeleton methods get no lattice options."""
    import numpy as np

    from probeplace.experiment import load_experiment_scene
    from probeplace.experiment._run import _placer_options

    t_frac = [0.013, 0.0, 0.029]
    cfg = to_config(compose(["placer=grid", f"scene.translate_frac=[{','.join(map(str, t_frac))}]"]))
    base = np.asarray(load_experiment_scene(to_config(compose([])).scene).bounds, np.float64)
    scene, t = load_experiment_scene(cfg.scene, with_translation=True)
    np.testing.assert_allclose(t, np.asarray(t_frac) * (base[1] - base[0]))
    np.testing.assert_allclose(np.asarray(scene.bounds, np.float64), base + t, rtol=1e-5, atol=1e-4)
    assert _placer_options(cfg, t)["shift"] == pytest.approx((-t).tolist())
    given = to_config(compose(["placer=grid", "+placer.options.shift=[1.0,0.0,0.0]"]))
    assert _placer_options(given, t)["shift"] == pytest.approx((np.array([1.0, 0.0, 0.0]) - t).tolist())
    assert _placer_options(given, np.zeros(3)) == {"shift": [1.0, 0.0, 0.0]}
    assert _placer_options(to_config(compose(["placer=skeleton"])), t) == {}


def test_backend_and_geometry_res_defaults_and_overrides():
    cfg = to_config(compose([]))
    assert (cfg.bake.backend, cfg.bake.geometry_res, cfg.eval.backend) == ("jax", None, "jax")
    cfg = to_config(compose(["bake.backend=mitsuba", "bake.geometry_res=64", "eval.backend=mitsuba"]))
    assert (cfg.bake.backend, cfg.bake.geometry_res, cfg.eval.backend) == ("mitsuba", 64, "mitsuba")


def test_trace_engine_reaches_the_evaluation():
    from probeplace.experiment._schema import eval_config

    assert eval_config(to_config(compose([]))).trace.engine == "wavefront"
    assert eval_config(to_config(compose(["eval.trace_engine=per_ray"]))).trace.engine == "per_ray"


@pytest.mark.parametrize(
    ("override", "key"),
    [({"bake": {"backend": "mitsuba"}}, "bake.backend"), ({"eval": {"backend": "mitsuba"}}, "eval.backend")],
)
def test_unloadable_mitsuba_is_refused_before_any_work(override, key, tmp_path, monkeypatch):
    """Without Mitsuba's module or LLVM variant (load_mitsuba's ImportError), run() refuses naming the key
    before placing; a disabled stage's backend is not checked."""
    import probeplace.render as render

    def missing():
        raise ImportError("backend='mitsuba' needs Mitsuba 3 (pip install mitsuba): no module")

    monkeypatch.setattr(render, "load_mitsuba", missing)  # the public face the runner reads it from
    with pytest.raises(ConfigError, match=rf"^{re.escape(key)}: backend='mitsuba' needs Mitsuba 3"):
        run({**override, "results_dir": str(tmp_path)})
    assert not [p for p in tmp_path.rglob("*") if p.is_file()]
    if key == "bake.backend":  # placements only: the bake's backend does not matter
        from probeplace.experiment._run import _check_backends

        _check_backends(
            to_config({"bake": {"enabled": False, "backend": "mitsuba"}, "eval": {"enabled": False}})
        )


def test_a_finished_run_from_before_a_new_key_is_still_the_same_run(tmp_path):
    """A key added to the schema later (a new library setting) is absent from an older run's config.yaml:
    that run had its default, so resuming keeps it; another value is a different run."""
    import yaml

    from probeplace.experiment._run import _check_same_config
    from probeplace.experiment._schema import config_to_dict

    cfg = to_config({})
    old = config_to_dict(cfg)
    del old["bake"]["moments_res"], old["eval"]["glossy_filter"]
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(old))
    _check_same_config(cfg, tmp_path)
    with pytest.raises(ConfigError, match=r"bake\.moments_res differ"):
        _check_same_config(to_config({"bake": {"moments_res": 8}}), tmp_path)


def test_memory_budget_and_valid_space_settings_name_their_runs():
    """A memory budget, a clearance and a region each get their own run folder (a sweep over them)."""
    base = run_name(to_config({}))
    mem = run_name(to_config({"placer": {"memory_budget": "64MiB"}}))
    assert "__bm64MiB__" in mem and mem != base
    clear = run_name(to_config({"placer": {"clearance": 0.05}}))
    band = run_name(to_config({"placer": {"region": {"height": [0.1, 1.5]}}}))
    assert len({base, mem, clear, band}) == 4 and "clearance=0.05" in clear and "region=" in band


def test_memory_budget_counts_probes_at_the_bake_settings(cornell):
    from probeplace.experiment._run import _placer_budget
    from probeplace.experiment._schema import bake_config
    from probeplace.probes import probe_bytes

    cfg = to_config({"placer": {"memory_budget": "1MiB"}, "bake": {"radiance_res": 16}})
    per_probe = probe_bytes(cornell, bake_config(cfg))
    assert _placer_budget(cfg, cornell) == 2**20 // per_probe >= 1
    finer = to_config({"placer": {"memory_budget": "1MiB"}, "bake": {"radiance_res": 32}})
    assert _placer_budget(finer, cornell) < _placer_budget(cfg, cornell)  # finer maps: fewer probes
    assert _placer_budget(to_config({"placer": {"budget": 9}}), cornell) == 9
