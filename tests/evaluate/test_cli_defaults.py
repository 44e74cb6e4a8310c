"""Issue 32 item 4: ``probeplace evaluate`` is the runner's evaluation. Its defaults are the runner's, read
from one place (``experiment._schema``: the oracle here is the runner's own config, as experiments/run.py
composes it from configs/), but for the glossy rays' engine (the wavefront tracer, the runner's presets');
``--trace-engine``, ``--timing-repeats`` and ``--glossy-ref-spp`` reach the library configs and bad values
are refused in one line before any slow work (``no_slow_work``)."""

from __future__ import annotations

import dataclasses

import pytest

from probeplace.cli import build_parser, main
from probeplace.cli._evaluate import bake_config, eval_config, resolved_options
from probeplace.evaluate import EvalConfig
from probeplace.experiment import bake_config as runner_bake_config
from probeplace.experiment import eval_config as runner_eval_config
from probeplace.experiment import to_config
from probeplace.probes import BakeConfig
from probeplace.probes.tracer._trace import ENGINES
from tests.experiment._util import compose
from tests.test_cli_checks import probe_json, refused


def _args(tmp_path, *extra: str):
    probes = probe_json(tmp_path / "p.json")
    argv = ["evaluate", "--scene", "cornell_box", "--probes", str(probes), "--out", str(tmp_path / "ev")]
    return build_parser().parse_args([*argv, *extra])


def _same_fields(a, b, *, skip=()) -> None:
    assert type(a) is type(b)
    for f in dataclasses.fields(a):
        if f.name not in skip:
            assert getattr(a, f.name) == getattr(b, f.name), f.name


def test_defaults_are_the_runners_field_by_field(tmp_path):
    args = _args(tmp_path)
    runner = to_config(compose([]))  # the runner's defaults, as run.py composes them
    cli_ev, run_ev = eval_config(args), runner_eval_config(runner)
    _same_fields(cli_ev, run_ev, skip=("trace", "seed"))  # the runner's seed is its run key's
    _same_fields(cli_ev.trace, run_ev.trace)
    assert (cli_ev.seed, resolved_options(args)["seed"]) == (runner.seed, runner.seed)
    _same_fields(bake_config(args), runner_bake_config(runner))
    assert resolved_options(args)["bake_spp"] == runner.bake.spp
    assert cli_ev.trace.engine == "wavefront"  # both run the wavefront light-field tracer


def test_noise_target_options_reach_the_library_configs(tmp_path):
    """Issue 33: ``auto`` counts and their targets and caps reach the evaluation and bake settings."""
    extra = ["--spp", "auto", "--glossy-ref-spp", "auto", "--noise-target", "0.1", "--max-spp", "64"]
    extra += ["--bake-spp", "auto", "--bake-noise-target", "0.2", "--bake-max-spp", "32"]
    args = _args(tmp_path, *extra)
    ev, bake = eval_config(args), bake_config(args)
    assert (ev.spp, ev.glossy_ref_spp, ev.noise_target, ev.max_spp) == ("auto", "auto", 0.1, 64)
    assert (bake.noise_target, bake.max_spp) == (0.2, 32)
    assert resolved_options(args)["bake_spp"] == "auto"


def test_options_reach_the_library_configs(tmp_path):
    extra = ["--trace-engine", "per_ray", "--timing-repeats", "1", "--glossy-ref-spp", "6", "--spp", "3"]
    extra += ["--max-depth", "5", "--hierarchy", "flat", "--radiance-res", "8", "--geometry-res", "32"]
    args = _args(tmp_path, *extra)
    ev, bake = eval_config(args), bake_config(args)
    assert isinstance(ev, EvalConfig) and isinstance(bake, BakeConfig)
    assert (ev.trace.engine, ev.trace.hierarchy) == ("per_ray", "flat")
    assert (ev.timing_repeats, ev.glossy_ref_spp, ev.spp, ev.max_depth) == (1, 6, 3, 5)
    assert (bake.radiance_res, bake.geometry_res) == (8, 32)


def test_the_run_gets_the_runners_settings_and_keys(tmp_path, capsys, no_slow_work, monkeypatch):
    """Through ``main``: the bake and the evaluation get the command line's settings over the runner's
    (``--trace-engine per_ray`` in the EvalConfig), the runner's keys, and each stage says so on stderr."""
    import jax

    import probeplace.evaluate
    import probeplace.geometry
    import probeplace.probes

    seen = {}

    class Stop(Exception):
        pass

    def bake(scene, probes, *, caster, radiance_fn, key, config):
        seen["bake"], seen["bake_key"] = config, key
        return probes

    def evaluate(scene, lf, *, view, config, caster, key, stage):
        seen["eval"], seen["eval_key"] = config, key
        raise Stop

    monkeypatch.setattr(probeplace.geometry, "make_caster", lambda *a, **k: None)
    monkeypatch.setattr(probeplace.probes, "path_traced_radiance", lambda *a, **k: lambda o, d, k: None)
    monkeypatch.setattr(probeplace.probes, "bake_probes", bake)
    monkeypatch.setattr(probeplace.evaluate, "evaluate", evaluate)
    probes = probe_json(tmp_path / "p.json")
    argv = ["evaluate", "--scene", "cornell_box", "--probes", str(probes), "--out", str(tmp_path / "ev")]
    with pytest.raises(Stop):
        main([*argv, "--trace-engine", "per_ray", "--seed", "3"])
    assert seen["eval"].trace.engine == "per_ray"
    runner = to_config(compose(["seed=3"]))
    _same_fields(seen["bake"], runner_bake_config(runner))
    k_bake, k_eval = jax.random.split(jax.random.key(3))  # as experiment._run._execute splits them
    for got, want in ((seen["bake_key"], k_bake), (seen["eval_key"], k_eval)):
        assert (jax.random.key_data(got) == jax.random.key_data(want)).all()
    err = capsys.readouterr().err
    assert "probeplace evaluate: [" in err and "] bake: 2 probes, 16² radiance maps" in err, err


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--trace-engine", "fast"], "--trace-engine: TraceConfig.engine must be one of"),
        (["--timing-repeats", "-1"], "--timing-repeats: EvalConfig.timing_repeats must be ≥ 0, got -1"),
        (["--glossy-ref-spp", "1"], "--glossy-ref-spp: EvalConfig.glossy_ref_spp must be an int ≥ 2"),
        (["--bake-spp", "0"], "--bake-spp must be a positive int or 'auto', got 0"),
        # issue 33, samples from a noise target
        (["--spp", "autox"], "--spp: EvalConfig.spp must be a positive int or 'auto', got 'autox'"),
        (["--glossy-ref-spp", "1.5"], "--glossy-ref-spp: EvalConfig.glossy_ref_spp must be an int ≥ 2 or"),
        (
            ["--noise-target", "0"],
            "--noise-target: EvalConfig.noise_target must be in (0, 1), got 0",
        ),
        (["--noise-target", "1"], "--noise-target: EvalConfig.noise_target must be in (0, 1)"),
        (["--spp", "auto", "--max-spp", "4"], "--max-spp: EvalConfig.max_spp must be ≥ pilot_spp (8)"),
        (["--bake-spp", "autox"], "--bake-spp must be a positive int or 'auto', got 'autox'"),
        (["--bake-noise-target", "1.5"], "--bake-noise-target: BakeConfig.noise_target must be in (0, 1)"),
        (["--bake-max-spp", "0"], "--bake-max-spp: BakeConfig.max_spp must be ≥ 1, got 0"),
    ],
    ids=[
        "trace-engine",
        "timing-repeats",
        "glossy-ref-spp",
        "bake-spp",
        "spp-autox",
        "glossy-ref-spp-float",
        "noise-target-0",
        "noise-target-1",
        "max-spp-below-pilot",
        "bake-spp-autox",
        "bake-noise-target",
        "bake-max-spp",
    ],
)
def test_bad_values_are_refused_in_one_line(tmp_path, capsys, no_slow_work, extra, needle):
    probes = probe_json(tmp_path / "p.json")
    argv = ["evaluate", "--scene", "cornell_box", "--probes", str(probes), "--out", str(tmp_path / "ev")]
    refused([*argv, *extra], capsys, needle)
    assert not (tmp_path / "ev").exists()


def test_help_shows_the_runners_defaults(capsys):
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    d = to_config({})
    assert f"(default: {d.eval.width}, the runner's eval.width)" in text
    assert f"(default: {d.tracer.spp}, the runner's tracer.spp)" in text
    assert f"(default: {d.bake.spp}, the runner's bake.spp)" in text
    assert f"(default: {d.eval.trace_engine}, the runner's eval.trace_engine)" in text
    assert all(e in text for e in ENGINES)
