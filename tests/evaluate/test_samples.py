"""Issue 33, "Samples from a noise target": the reference's counts chosen from a pilot pass.

Oracles: (a) the final pass's own measured noise floor ÷ black MSE (``noise_floor_*`` / ``mse_black_*``,
the figures every evaluation reports) is at most the target for each scored component, not the pilot's
prediction; (b) the chosen count is the closed form of the pilot's 1/spp rule, recomputed from the pilot
figures the result reports (``evaluate._samples``); (c) a fixed count gives the metrics of the steps run
one by one (the evaluation's code path before counts could be chosen) and an ``"auto"`` run gives the
metrics of a fixed run at the counts it chose; a pilot whose count is chosen is the final pass. The scene
is the Cornell box at 16×16 pixels with probes baked by a cheap stand-in (the probes do not enter the
reference's noise).
"""

from __future__ import annotations

import dataclasses
import logging
import math

import pytest

from probeplace._core import PILOT_Z, ConfigError, ResourceError, smallest_count
from probeplace.evaluate import EvalConfig, IndirectScores, check_eval_memory, evaluate
from probeplace.evaluate._samples import (
    COUNT_OF,
    CountChoice,
    Pilot,
    choose_count,
    predicted_floor_over_black,
    samples_metrics,
)

#: Below the glossy pilot's own 0.04 at 8 paths (measured), so both counts are chosen above the pilot.
TARGET = 0.03
#: Metrics that are wall times: the only ones two runs of the same numbers may differ in.
TIMES = ("shading_s_per_frame", "shading_compile_s", "reference_s")


def _eval(cornell, **kw):
    scene, lf, caster, base = cornell
    return evaluate(scene, lf, view="front", config=dataclasses.replace(base, **kw), caster=caster).metrics


@pytest.fixture(scope="module")
def auto(cornell):
    return _eval(cornell, spp="auto", glossy_ref_spp="auto", noise_target=TARGET, pilot_spp=8)


def _same(a, b, path=""):
    """Equal metrics, NaN equal to NaN (an undefined figure is undefined in both)."""
    if isinstance(a, dict):
        assert set(a) == set(b), path
        for k in a:
            _same(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, float) and math.isnan(a):
        assert isinstance(b, float) and math.isnan(b), path
    else:
        assert a == b, (path, a, b)


def _drop(m: dict, *keys: str) -> dict:
    return {k: v for k, v in m.items() if k not in (*TIMES, *keys)}


def test_the_target_is_met_by_the_final_pass(auto):
    """(a) The final pass's measured floor ÷ black MSE ≤ the target for each scored component."""
    s = auto["samples"]
    assert s["reference_chosen_by"] == s["glossy_ref_chosen_by"] == "target"
    for c in COUNT_OF:
        measured = auto[f"noise_floor_{c}"] / auto[f"mse_black_{c}"]
        assert measured <= TARGET, c
        assert s["floor_over_black"][c] == measured
        # the pilot alone did not meet it: the choice did the work
        assert s["pilot_floor_over_black"][c] > TARGET, c
    assert s["target_met"] is True
    assert (auto["spp"], auto["glossy_ref_spp"]) == (s["reference_spp"], s["glossy_ref_spp"])


def test_the_count_is_the_closed_form_of_the_pilot_rule(auto):
    """(b) Each count is the smallest of the pilot count and the powers of two above it that the 1/spp
    rule predicts to meet the target: s ≥ p · f⁺ (1 − t) / (t (b_p − f_p)), f⁺ = f_p + 1.645 σ_p."""
    s = auto["samples"]
    p = s["pilot_spp"]
    for c, count in (("diffuse_indirect", "reference_spp"), ("glossy_indirect", "glossy_ref_spp")):
        f, se, b = s["pilot_floor"][c], s["pilot_floor_se"][c], s["pilot_black"][c]
        f_up = f + PILOT_Z * se
        s_min = p * f_up * (1 - TARGET) / (TARGET * (b - f))
        want = p if s_min <= p else 2 ** math.ceil(math.log2(s_min))
        assert s[count] == min(want, s["max_spp"]) == want, c
        # the prediction the result reports is the rule's at that count, and the count below misses
        pilot = Pilot(p, f, se, b, 0.0)
        assert s["predicted_floor_over_black"][c] == predicted_floor_over_black(pilot, s[count])
        assert s["predicted_floor_over_black"][c] <= TARGET
        below = s[count] // 2
        assert below < p or predicted_floor_over_black(pilot, below) > TARGET


def test_auto_is_a_fixed_run_at_the_chosen_counts(cornell, auto):
    """(c) A fixed run at the counts ``auto`` chose gives the same metrics, but for how they were chosen
    (``samples``) and the wall times."""
    fixed = _eval(cornell, spp=auto["spp"], glossy_ref_spp=auto["glossy_ref_spp"], noise_target=TARGET)
    _same(_drop(fixed, "samples"), _drop(auto, "samples"))
    s = fixed["samples"]
    assert s["reference_chosen_by"] == s["glossy_ref_chosen_by"] == "fixed"
    assert s["pilot_spp"] is None and s["pilot_floor"] == {c: None for c in COUNT_OF}
    assert s["floor_over_black"] == auto["samples"]["floor_over_black"] and s["target_met"] is True


def test_fixed_counts_are_the_steps_run_one_by_one(cornell):
    """(c) With fixed counts ``evaluate`` is its steps run one by one and scored (the evaluation as it was
    before counts could be chosen): the same metrics bit for bit, but the wall times."""
    from probeplace.evaluate import score
    from tests.evaluate.conftest import evaluation_steps

    scene, lf, caster, base = cornell
    config = dataclasses.replace(base, spp=8, glossy_ref_spp=2)
    got = evaluate(scene, lf, view="front", config=config, caster=caster).metrics
    want = score(scene, lf, "front", config, *evaluation_steps(scene, lf, caster, config)).metrics
    _same(_drop(got), _drop(want))
    assert (got["spp"], got["glossy_ref_spp"]) == (8, 2)


def test_a_pilot_whose_count_is_chosen_is_the_final_pass(cornell):
    """A generous target is met at the pilot's count: the pilot's pass is the final one (its floor is the
    reported floor, exactly), and the count is the pilot's."""
    m = _eval(cornell, spp="auto", noise_target=0.9, pilot_spp=8)
    s = m["samples"]
    assert s["reference_spp"] == m["spp"] == 8 and s["reference_chosen_by"] == "target"
    assert s["pilot_floor"]["diffuse_indirect"] == m["noise_floor_diffuse_indirect"]
    assert s["glossy_ref_chosen_by"] == "fixed" and s["pilot_floor"]["glossy_indirect"] is None


def test_a_cap_that_cannot_meet_the_target_renders_at_the_cap(cornell, caplog):
    """The cap wins over the target: the run proceeds at ``max_spp``, says ``target_met: false`` and
    warns."""
    with caplog.at_level(logging.WARNING, logger="probeplace"):
        m = _eval(cornell, spp="auto", noise_target=TARGET, pilot_spp=8, max_spp=16)
    s = m["samples"]
    assert m["spp"] == s["reference_spp"] == 16
    assert s["floor_over_black"]["diffuse_indirect"] > TARGET and s["target_met"] is False
    assert "max_spp=16 cannot reach the target" in caplog.text
    assert "above the noise target" in caplog.text


def test_the_rule_on_synthetic_pilots():
    """The count search and the prediction on hand-made pilot figures (closed forms)."""
    assert smallest_count(lambda s: s >= 5, lo=1, cap=64) == (8, True)
    assert smallest_count(lambda s: s >= 6, lo=6, cap=64) == (6, True)  # the pilot's own count
    assert smallest_count(lambda s: s >= 7, lo=6, cap=64) == (8, True)
    assert smallest_count(lambda s: False, lo=8, cap=100) == (100, False)
    assert smallest_count(lambda s: s >= 100, lo=8, cap=100) == (100, True)
    # floor 1, black 1.5 (μ² = 0.5) at 8 paths: s ≥ 8 · 0.95 / (0.05 · 0.5) = 304 → 512
    pilot = Pilot(spp=8, floor=1.0, floor_se=0.0, black=1.5, seconds=0.0)
    assert choose_count(pilot, 0.05, 1024) == (512, True)
    assert choose_count(pilot, 0.05, 256) == (256, False)
    f = 8 / 512
    assert predicted_floor_over_black(pilot, 512) == pytest.approx(f / (0.5 + f), rel=1e-15)
    # the standard error raises the floor it plans for
    assert choose_count(dataclasses.replace(pilot, floor_se=0.5 / PILOT_Z), 0.05, 1024)[0] == 512
    assert choose_count(dataclasses.replace(pilot, floor_se=1.0 / PILOT_Z), 0.05, 1024)[0] == 1024
    # no noise: the pilot's count; all noise: never
    assert choose_count(dataclasses.replace(pilot, floor=0.0), 0.05, 1024) == (8, True)
    assert predicted_floor_over_black(dataclasses.replace(pilot, black=0.9), 8) == math.inf


def test_the_samples_group_is_json_without_infinities():
    """An all-noise pilot predicts ``inf`` (no count meets a target): the group says None, since
    ``metrics.json`` is strict JSON (``write_json_atomic`` refuses infinities); a black component
    without noise has a floor of 0 of its black MSE."""
    import json

    noisy = Pilot(spp=8, floor=1.0, floor_se=0.0, black=0.9, seconds=0.0)
    choices = {
        "diffuse_indirect": CountChoice(64, "target", noisy, predicted_floor_over_black(noisy, 64)),
        "glossy_indirect": CountChoice(4, "fixed"),
    }
    scores = {
        "diffuse_indirect": IndirectScores(noise_floor=1e-3, mse_black=2e-3),
        "glossy_indirect": IndirectScores(noise_floor=0.0, mse_black=0.0),
    }
    out = samples_metrics(EvalConfig(spp="auto", max_spp=64), choices, scores).to_json()
    json.dumps(out, allow_nan=False)
    assert out["predicted_floor_over_black"] == {"diffuse_indirect": None, "glossy_indirect": None}
    assert out["floor_over_black"] == {"diffuse_indirect": 0.5, "glossy_indirect": 0.0}
    assert out["target_met"] is False and out["pilot_floor"]["glossy_indirect"] is None


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"spp": "autox"}, r"^EvalConfig\.spp must be a positive int or 'auto', got 'autox'$"),
        ({"glossy_ref_spp": "Auto"}, r"^EvalConfig\.glossy_ref_spp must be an int ≥ 2 or 'auto'"),
        ({"noise_target": 0.0}, r"^EvalConfig\.noise_target must be in \(0, 1\), got 0\.0$"),
        ({"noise_target": 1.0}, r"^EvalConfig\.noise_target must be in \(0, 1\)"),
        ({"pilot_spp": 1}, r"^EvalConfig\.pilot_spp must be ≥ 2, got 1$"),
        ({"max_spp": 4}, r"^EvalConfig\.max_spp must be ≥ pilot_spp \(8\)"),
    ],
)
def test_bad_targets_are_one_line_config_errors(kw, match):
    with pytest.raises(ConfigError, match=match):
        EvalConfig(**kw)


def test_memory_is_checked_at_the_cap(monkeypatch):
    """An ``"auto"`` count is checked at ``max_spp`` before any work: the renderer's path batch grows with
    the count (``check_image_memory``: min(2¹⁸, pixels × spp) paths of ~200 bytes)."""
    monkeypatch.setenv("PROBEPLACE_MAX_BYTES", str(8 << 20))  # 8 MiB: 8×8 × 8 spp fits, × 4096 does not
    check_eval_memory(EvalConfig(width=8, height=8, spp=8), "test")
    with pytest.raises(ResourceError, match="4096 spp"):
        check_eval_memory(EvalConfig(width=8, height=8, spp="auto", max_spp=4096), "test")
