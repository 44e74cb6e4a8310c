"""evaluate() on a tiny Cornell box configuration: files, metric invariants, common random numbers.

Oracles: invariants of the metrics (finite MSEs, positive noise floors, memory adds up, unresolved share
a fraction), the images' defining relations (full = emission + direct + diffuse + glossy; error = |probe −
reference|) and the purpose of common random numbers: the glossy MSE against the CRN reference is below
the MSE of the same probe image against an independent reference render. The error taken apart
(``_decompose.py``): on a hand-made case and on the real run the per-status terms add up to the glossy
MSE, the trace's share and the perfect-trace MSE add up to it, the resolved-only MSE is the MSE with the
unresolved rays given the reference radiance, and the bootstrap interval is deterministic and contains
the MSE.
"""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import ConfigError
from probeplace.evaluate import (
    EvalConfig,
    agreeing_hits,
    bootstrap_ci,
    converged_sq_error,
    evaluate,
    glossy_terms,
    hit_agreement,
    relative_mse,
    sample_charges,
    sample_errors,
    tail_count,
    tail_index,
    top_share,
    write_evaluation,
)
from probeplace.geometry import BruteForceCaster
from probeplace.probes import BakeConfig, bake_probes, path_traced_radiance
from probeplace.scene import load_scene
from tests.helpers import albedo_lit, grid_probe_set

KEYS = (
    "mse_glossy_indirect",
    "noise_floor_glossy_indirect",
    "mse_diffuse_indirect",
    "noise_floor_diffuse_indirect",
    "mse_full",
    "noise_floor_full",
    "light_leak_energy",
    "unresolved_share",
    "origin_seen_share",
    "unresolved_seen_share",
    "shading_s_per_frame",
    "shading_compile_s",
    "memory_bytes",
    "n_probes",
    "view",
    "width",
    "height",
    "shading",
    "mse_glossy_perfect_trace",
    "mse_glossy_trace_share",
    "trace_excess",
    "mse_glossy_by_status",
    "mse_glossy_resolved_only",
    "glossy_hit_agreement",
    "perfect_trace_fallbacks",
    "relmse_glossy_indirect",
    "relmse_diffuse_indirect",
    "relmse_full",
    "ci95_mse_glossy_indirect",
    "ci95_mse_glossy_perfect_trace",
    "ci95_mse_diffuse_indirect",
    "ci95_mse_full",
)


@pytest.fixture(scope="module")
def cornell_eval():
    scene = load_scene("cornell_box")
    caster = BruteForceCaster(scene)
    probes = grid_probe_set(scene, (3, 3, 3))
    cfg = BakeConfig(
        radiance_res=16, irradiance_res=6, moments_res=8, n_sub=1, probes_per_batch=27, progress=False
    )
    radiance = albedo_lit(scene, caster)
    lf = bake_probes(scene, probes, caster=caster, radiance_fn=radiance, key=jax.random.key(0), config=cfg)
    config = EvalConfig(width=12, height=10, spp=8, glossy_spp=4, glossy_ref_spp=2, timing_repeats=1)
    result = evaluate(scene, lf, view="front", config=config, caster=caster)
    return scene, lf, caster, result


def test_evaluate_writes_all_files(cornell_eval, tmp_path):
    result = cornell_eval[3]
    paths = write_evaluation(result, tmp_path / "eval")
    m = json.loads((tmp_path / "eval" / "metrics.json").read_text())
    for k in KEYS:
        assert k in m, k
    for c in ("diffuse_indirect", "glossy_indirect", "full"):
        for stem in (f"ref_{c}", f"probe_{c}", f"error_{c}", f"error_{c}_false"):
            assert (tmp_path / "eval" / f"{stem}.png").is_file(), stem
    assert (tmp_path / "eval" / "images.exr").is_file()
    assert set(paths) >= {"metrics", "exr"}


def test_evaluation_size_bound_and_all_or_nothing(cornell_eval, tmp_path, monkeypatch):
    """The up-front space check's bound holds for the files written (their sizes are the oracle), a
    rewrite replaces an evaluation in place, and a write that fails part-way (a full disk) leaves neither
    the folder nor its staging folder behind."""
    import errno

    from probeplace.evaluate import _write
    from probeplace.evaluate._evaluate import EVAL_IMAGES

    result = cornell_eval[3]
    assert tuple(result.images) == EVAL_IMAGES
    h, w = np.asarray(result.images["probe_full"]).shape[:2]
    paths = write_evaluation(result, tmp_path / "eval")
    written = sum(p.stat().st_size for p in (tmp_path / "eval").iterdir())
    assert written <= _write.evaluation_bytes(w, h)
    assert len(list((tmp_path / "eval").iterdir())) == len(paths)
    write_evaluation(result, tmp_path / "eval")  # over a finished one: same files, no leftovers
    assert sorted(p.name for p in tmp_path.iterdir()) == ["eval"]
    assert len(list((tmp_path / "eval").iterdir())) == len(paths)

    def full_disk(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(_write, "save_exr", full_disk)
    with pytest.raises(OSError):
        write_evaluation(result, tmp_path / "new" / "eval")
    assert list((tmp_path / "new").iterdir()) == []


def test_untimed_shading_same_figures(cornell_eval):
    """``timing_repeats=0`` shades once, untimed: both times null, every other figure as the timed run's
    (the same inputs and keys; the timed run's repeats only run the shading again)."""
    scene, lf, caster, timed = cornell_eval
    config = EvalConfig(width=12, height=10, spp=8, glossy_spp=4, glossy_ref_spp=2, timing_repeats=0)
    m = evaluate(scene, lf, view="front", config=config, caster=caster).metrics
    assert m["shading_s_per_frame"] is None and m["shading_compile_s"] is None
    assert timed.metrics["shading_s_per_frame"] is not None
    skip = {"shading_s_per_frame", "shading_compile_s", "timing_repeats", "reference_s"}
    for k, v in timed.metrics.items():
        if k not in skip and not k.endswith("_s"):
            assert m[k] == v, k


def test_metrics_invariants(cornell_eval):
    _, lf, _, result = cornell_eval
    m = result.metrics
    for k in ("mse_glossy_indirect", "mse_diffuse_indirect", "mse_full"):
        assert np.isfinite(m[k]) and m[k] >= 0, k
    for k in ("noise_floor_glossy_indirect", "noise_floor_diffuse_indirect", "noise_floor_full"):
        assert m[k] > 0, k
    assert 0.0 <= m["unresolved_share"] <= 1.0
    # the unresolved share splits over rays whose origin a probe sees (share s) and the rest:
    # s·u_seen ≤ unresolved ≤ s·u_seen + (1 − s)
    s, u_seen = m["origin_seen_share"], m["unresolved_seen_share"]
    assert 0.0 < s <= 1.0 and 0.0 <= u_seen <= 1.0  # a 3×3×3 grid in the open box sees most origins
    assert s * u_seen - 1e-12 <= m["unresolved_share"] <= s * u_seen + (1 - s) + 1e-12
    assert m["shading_s_per_frame"] > 0 and m["shading_compile_s"] >= 0
    mem = m["memory_bytes"]
    assert mem["total"] == sum(mem["by_map"].values())
    assert mem["per_probe"] * m["n_probes"] == pytest.approx(mem["total"])
    # radiance: n × (R+2)² × 3 float32
    assert mem["by_map"]["radiance"] == lf.pos_world.shape[0] * 18 * 18 * 3 * 4
    assert m["n_probes"] == 27 and (m["width"], m["height"]) == (12, 10)
    # the black-image baseline is the mean square of the reference each MSE is taken against
    im = result.images
    for c in ("glossy_indirect", "diffuse_indirect"):
        ref = np.asarray(im[f"ref_{c}"], np.float64)
        assert m[f"mse_black_{c}"] == pytest.approx(np.mean(ref**2), rel=1e-5), c
        err = np.asarray(im[f"error_{c}"], np.float64)
        assert m[f"mse_{c}"] == pytest.approx(np.mean(err**2), rel=1e-4), c
    json.dumps(m, allow_nan=False)


def test_images_compose(cornell_eval):
    _, _, _, result = cornell_eval
    im = result.images
    for v in im.values():
        assert v.shape == (10, 12, 3) and v.dtype == np.float32
    np.testing.assert_allclose(
        im["probe_full"],
        im["ref_emission"] + im["ref_direct"] + im["probe_diffuse_indirect"] + im["probe_glossy_indirect"],
        rtol=1e-5,
        atol=1e-6,
    )
    for c in ("diffuse_indirect", "glossy_indirect", "full"):
        np.testing.assert_allclose(im[f"error_{c}"], np.abs(im[f"probe_{c}"] - im[f"ref_{c}"]), atol=1e-6)
    # The probe diffuse indirect is non-negative and not all zero in the lit box.
    assert im["probe_diffuse_indirect"].min() >= 0 and im["probe_diffuse_indirect"].max() > 0


def test_common_random_numbers_reduce_glossy_mse(cornell_eval):
    m = cornell_eval[3].metrics
    assert m["mse_glossy_indirect"] < m["mse_glossy_indirect_no_crn"]


def test_bad_config_and_view(cornell_eval):
    scene, lf, caster, _ = cornell_eval
    with pytest.raises(ConfigError):
        EvalConfig(shading="phong")
    with pytest.raises(ConfigError):
        EvalConfig(max_depth=2)
    with pytest.raises(ConfigError):
        evaluate(scene, lf, view="nowhere", config=EvalConfig(width=4, height=4), caster=caster)


def _synthetic_samples(n_px=50, spp=4, seed=0):
    rng = np.random.default_rng(seed)
    n = n_px * spp
    w = rng.uniform(0.0, 1.0, (n, 3)) * (rng.uniform(size=(n, 1)) > 0.1)  # some samples without a ray
    l_ref = rng.exponential(1.0, (n, 3))
    l_probe = l_ref + rng.normal(0.0, 0.3, (n, 3))
    l_perfect = l_ref + rng.normal(0.0, 0.1, (n, 3))
    status = rng.choice([0, 1, 2], n, p=[0.2, 0.7, 0.1])
    return w, l_probe, l_ref, l_perfect, status, spp


def test_glossy_terms_add_up_on_a_synthetic_case():
    w, lp, lr, lq, st, spp = _synthetic_samples()
    t = glossy_terms(w, lp, lr, lq, st, spp)
    img = lambda rad: (w * rad).reshape(-1, spp, 3).mean(axis=1)
    assert t["mse"] == pytest.approx(np.mean((img(lp) - img(lr)) ** 2), rel=1e-12)
    assert t["mse_perfect_trace"] == pytest.approx(np.mean((img(lq) - img(lr)) ** 2), rel=1e-12)
    assert sum(t["by_status"].values()) == pytest.approx(t["mse"], rel=1e-12)
    assert t["trace_share"] + t["mse_perfect_trace"] == pytest.approx(t["mse"], rel=1e-12)
    assert t["trace_excess"] == pytest.approx(t["mse"] / t["mse_perfect_trace"] - 1, rel=1e-12)
    # resolved only = the image whose unresolved rays carry the reference radiance
    lp_res = np.where((st == 2)[:, None], lr, lp)
    assert t["resolved_only"] == pytest.approx(np.mean((img(lp_res) - img(lr)) ** 2), rel=1e-12)
    assert np.mean(t["sq_px"]) == pytest.approx(t["mse"], rel=1e-12)
    # By hand: one pixel, two samples with errors a and b (w = 1, S = 2): MSE = ((a + b)/2)², the hit
    # sample is charged (a/2)·(a + b)/2 and the unresolved one (b/2)·(a + b)/2.
    a, b = 0.4, -0.1
    one = np.ones((2, 3))
    t1 = glossy_terms(one, np.array([[a] * 3, [b] * 3]), 0 * one, 0 * one, np.array([1, 2]), 2)
    assert t1["mse"] == pytest.approx(((a + b) / 2) ** 2)
    assert t1["by_status"]["hit"] == pytest.approx(a / 2 * (a + b) / 2)
    assert t1["by_status"]["unresolved"] == pytest.approx(b / 2 * (a + b) / 2)
    assert t1["by_status"]["miss"] == 0.0 and t1["trace_excess"] is None


def test_converged_mse_by_hand_and_in_glossy_terms():
    """The converged MSE (``_decompose`` docstring): by hand, the two-sample pixel (a, b) gives a·b, one
    sample's lone error gives 0 (the plain MSE gives its square ÷ S²); ``glossy_terms`` reports its image
    mean, and nothing at one sample a pixel."""
    a, b, big = 0.4, -0.1, 7.0
    e = lambda errs: sample_errors(
        np.ones((len(errs), 3)), np.array(errs)[:, None] * np.ones(3), 0.0, len(errs)
    )
    assert converged_sq_error(*e([a, b])) == pytest.approx([a * b])
    assert converged_sq_error(*e([big, 0.0, 0.0, 0.0])) == pytest.approx([0.0], abs=1e-15)
    assert np.mean(e([big, 0.0, 0.0, 0.0])[1] ** 2) == pytest.approx((big / 4) ** 2)
    w, lp, lr, lq, st, spp = _synthetic_samples()
    t = glossy_terms(w, lp, lr, lq, st, spp)
    assert t["converged"] == pytest.approx(
        np.mean(converged_sq_error(*sample_errors(w, lp, lr, spp))), rel=1e-12
    )
    assert t["sq_px_converged"].shape == t["sq_px"].shape
    one = glossy_terms(w[:8], lp[:8], lr[:8], lq[:8], st[:8], 1)
    assert one["converged"] is None and one["sq_px_converged"] is None
    with pytest.raises(ValueError, match="at least 2 samples"):
        converged_sq_error(*sample_errors(w[:8], lp[:8], lr[:8], 1))


def test_converged_mse_is_unbiased_where_the_plain_mse_is_not():
    """Closed form: pixels of known mean error μ_p, S samples each with noise of variance σ² (heavy-tailed:
    Student's t with 3 degrees of freedom, σ² = 3 × scale²). Over R replicate images the plain MSE's mean
    is mean(μ²) + σ²/S, the converged MSE's mean(μ²); each checked within 5 standard errors of the
    replicates' mean (fixed seed)."""
    rng = np.random.default_rng(7)
    n_px, S, R, scale = 64, 8, 4000, 0.5
    mu = rng.uniform(-1.0, 1.0, n_px)
    d = mu[None, :, None, None] + scale * rng.standard_t(3, (R, n_px, S, 1))  # one channel
    e_s = np.broadcast_to(d / S, (R, n_px, S, 3)).reshape(R, n_px * S, 3)
    plain = np.array([np.mean(e.reshape(n_px, S, 3).sum(axis=1) ** 2) for e in e_s])
    conv = np.array([np.mean(converged_sq_error(e, e.reshape(n_px, S, 3).sum(axis=1))) for e in e_s])
    truth, noise = np.mean(mu**2), 3 * scale**2 / S
    se = lambda v: np.std(v) / np.sqrt(R)
    assert abs(conv.mean() - truth) < 5 * se(conv)
    assert abs(plain.mean() - (truth + noise)) < 5 * se(plain)
    assert plain.mean() - truth > 10 * se(plain)  # the plain MSE's bias is plain to see


def test_bootstrap_relmse_and_agreement():
    rng = np.random.default_rng(1)
    v = rng.pareto(1.5, 4000)  # heavy-tailed per-pixel squared errors
    ci = bootstrap_ci(v, n_resamples=500, seed=0)
    assert ci[0] <= v.mean() <= ci[1]
    assert ci == bootstrap_ci(v, n_resamples=500, seed=0)  # deterministic
    assert ci != bootstrap_ci(v, n_resamples=500, seed=1)
    # relative MSE: scale-invariant (ε is relative to the reference's mean luminance) and 0 when equal
    p, r = rng.uniform(0, 1, (8, 8, 3)), rng.uniform(0, 1, (8, 8, 3))
    assert relative_mse(7.0 * p, 7.0 * r) == pytest.approx(relative_mse(p, r), rel=1e-12)
    assert relative_mse(r, r) == 0.0 and relative_mse(p, 0 * r) is None
    lum = lambda x: x @ np.array([0.2126, 0.7152, 0.0722])
    eps = 0.01 * np.mean(lum(r)) ** 2
    assert relative_mse(p, r) == pytest.approx(np.mean((lum(p) - lum(r)) ** 2 / (lum(r) ** 2 + eps)))
    # agreement over TraceStatus.HIT rays only; an exact miss disagrees
    st = np.array([1, 1, 1, 1, 0, 2])
    t_lf = np.array([1.0, 2.0, 3.0, 4.0, np.inf, 1.0])
    t_ex = np.array([1.01, 2.2, np.inf, 4.0, 5.0, 1.0])
    assert hit_agreement(t_lf, t_ex, st, rtol=0.02) == (0.5, 4)
    assert hit_agreement(t_lf, t_ex, np.zeros(6, int)) == (None, 0)
    np.testing.assert_array_equal(agreeing_hits(t_lf, t_ex, st, rtol=0.02), [1, 0, 0, 1, 0, 0])
    np.testing.assert_array_equal(agreeing_hits(t_lf, t_ex, st, rtol=0.02, atol=0.2), [1, 1, 0, 1, 0, 0])


def test_sample_charges_add_up_over_parts_and_pixels():
    """The charges of all samples add up to the MSE; those of some pixels' samples to those pixels' sum of
    squared errors ÷ (pixels × channels); charges of parts that add up to a sample's error add up to its
    charge."""
    rng = np.random.default_rng(4)
    spp, n_px = 4, 50
    w, lp, lr = (rng.uniform(0, 1, (n_px * spp, 3)) for _ in range(3))
    e_s, e_px = sample_errors(w, lp, lr, spp)
    c = sample_charges(e_s, e_px)
    assert c.sum() == pytest.approx(np.mean(e_px**2), rel=1e-12)
    some = np.arange(n_px) % 3 == 0
    per_px = c.reshape(n_px, spp).sum(axis=1)
    assert per_px[some].sum() == pytest.approx(np.sum(e_px[some] ** 2) / e_px.size, rel=1e-12)
    part = w * (lp - 0.5) / spp  # e_s = part + (e_s − part)
    np.testing.assert_allclose(sample_charges(part, e_px) + sample_charges(e_s - part, e_px), c, rtol=1e-12)


def test_top_share_is_the_largest_pixels_part_of_the_sum():
    """Closed forms: the k largest of a known array, ties, k past the size, no error at all."""
    sq = np.array([[3.0, 1.0], [4.0, 2.0]])
    assert top_share(sq, 1) == 0.4 and top_share(sq, 2) == 0.7 and top_share(sq, 9) == 1.0
    assert top_share(np.full(10, 2.0), 3) == pytest.approx(0.3)  # ties: any three of them
    assert top_share(np.zeros(5), 1) is None
    v = np.random.default_rng(2).pareto(1.5, 1000)  # against a full sort
    assert top_share(v, 10) == pytest.approx(np.sort(v)[-10:].sum() / v.sum(), rel=1e-12)


def test_tail_count_is_the_percentage_rounded_down_one_at_least():
    assert tail_count(3072) == 30 and tail_count(27_648) == 276  # 64×48 and 192×144 images
    assert tail_count(50) == 1 and tail_count(0) == 1
    assert tail_count(100, 5.0) == 5 and tail_count(6, 100 / 6) == 1 and tail_count(400, 100.0) == 400


def test_tail_index_recovers_a_pareto_tail():
    """Closed form: Hill's estimate is the maximum-likelihood α of a Pareto tail, with standard error
    α / √k; 200,000 draws, k = 2,000: within 0.05 α + 0.075 (0.115, 0.15 and 0.225 at α = 0.8, 1.5 and
    3: 6.4, 4.5 and 3.4 standard errors).
    Invariants: a scale does not move it; too few positive values or a flat top give None."""
    rng = np.random.default_rng(7)
    for alpha in (0.8, 1.5, 3.0):
        x = rng.pareto(alpha, 200_000) + 1.0  # numpy's Lomax + 1: Pareto with x_m = 1
        assert tail_index(x, 2000) == pytest.approx(alpha, abs=0.05 * alpha + 0.075), alpha
        assert tail_index(37.0 * x, 2000) == pytest.approx(tail_index(x, 2000), rel=1e-9)
    # the slow obvious form, a full sort
    v = rng.pareto(1.2, 1000) + 1.0
    s = np.sort(v)[::-1]
    assert tail_index(v, 10) == pytest.approx(1.0 / np.mean(np.log(s[:10] / s[10])), rel=1e-12)
    assert tail_index(np.array([0.0, 0.0, 5.0]), 1) is None  # one positive value: nothing to divide by
    assert tail_index(np.full(10, 2.0), 3) is None  # the top equals the next: no tail


def test_decomposition_adds_up_on_the_real_run(cornell_eval):
    m, im = cornell_eval[3].metrics, cornell_eval[3].images
    mse = m["mse_glossy_indirect"]
    assert sum(m["mse_glossy_by_status"].values()) == pytest.approx(mse, rel=1e-9)
    assert m["mse_glossy_trace_share"] + m["mse_glossy_perfect_trace"] == pytest.approx(mse, rel=1e-12)
    assert m["trace_excess"] == pytest.approx(mse / m["mse_glossy_perfect_trace"] - 1, rel=1e-9)
    assert 0 <= m["mse_glossy_resolved_only"] and 0 <= m["mse_glossy_perfect_trace"]
    assert sum(m["glossy_status_share"].values()) == pytest.approx(1.0)
    assert m["glossy_status_share"]["unresolved"] == m["unresolved_share"]
    assert m["glossy_hit_agreement"] is None or 0 <= m["glossy_hit_agreement"] <= 1
    assert 0 <= m["perfect_trace_fallback_share"] <= 1
    # the perfect-trace image is the one its MSE is taken of (float32 image: rel 1e-4)
    pt = np.asarray(im["perfect_trace_glossy_indirect"], np.float64)
    ref = np.asarray(im["ref_glossy_indirect"], np.float64)
    assert m["mse_glossy_perfect_trace"] == pytest.approx(np.mean((pt - ref) ** 2), rel=1e-4)
    for k in ("glossy_indirect", "glossy_perfect_trace", "diffuse_indirect", "full"):
        lo, hi = m[f"ci95_mse_{k}"]
        assert lo <= m[f"mse_{k}"] <= hi, k
    for k in ("relmse_glossy_indirect", "relmse_diffuse_indirect", "relmse_full"):
        assert m[k] is None or (np.isfinite(m[k]) and m[k] >= 0), k
    # bootstrap over the same pixels with the same seed: the same interval
    err = np.asarray(im["error_diffuse_indirect"], np.float64)
    ci = bootstrap_ci(np.mean(err**2, axis=-1), n_resamples=m["bootstrap_resamples"], seed=0)
    np.testing.assert_allclose(ci, m["ci95_mse_diffuse_indirect"], rtol=1e-4)  # float32 error image


@pytest.mark.slow
def test_glossy_mse_approaches_noise_floor_with_fine_probes():
    """With finer probe maps the representation error shrinks, so the CRN glossy MSE gets closer to
    its noise floor (the probe radiance is then limited by the bake's own noise)."""
    scene = load_scene("cornell_box")
    caster = BruteForceCaster(scene)
    probes = grid_probe_set(scene, (4, 4, 4))
    ratios = []
    for res in (8, 32):
        cfg = BakeConfig(radiance_res=res, n_sub=1, probes_per_batch=16, progress=False)
        lf = bake_probes(
            scene,
            probes,
            caster=caster,
            radiance_fn=path_traced_radiance(scene, spp=8, caster=caster),
            key=jax.random.key(1),
            config=cfg,
        )
        config = EvalConfig(width=24, height=24, spp=16, glossy_spp=8, glossy_ref_spp=8, timing_repeats=1)
        m = evaluate(scene, lf, view="front", config=config, caster=caster).metrics
        ratios.append(m["mse_glossy_indirect"] / m["noise_floor_glossy_indirect"])
    assert ratios[1] < ratios[0]


def test_probe_error_adds_up_on_the_real_run(cornell_eval, tmp_path):
    """Each probe's share of the error (``_attribute``): per component, the probes' shares and the
    unattributed rest add up to the MSE in metrics.json; the file holds the baked set's rows."""
    _, lf, _, result = cornell_eval
    pe = result.probe_error
    m = result.metrics
    n = int(lf.pos_world.shape[0])
    for key in ("diffuse_indirect", "glossy_indirect", "glossy_indirect_unresolved"):
        assert pe[key].shape == (n,) and np.all(pe[key] >= 0)
    d = pe["diffuse_indirect"].sum() + pe["unattributed_diffuse_indirect"]
    assert d == pytest.approx(m["mse_diffuse_indirect"], rel=1e-9)  # float64 sums of float32 images
    g = (
        pe["glossy_indirect"].sum()
        + pe["unattributed_glossy_indirect_unresolved"]
        + pe["unattributed_glossy_indirect_miss"]
        + pe["unattributed_glossy_indirect_other"]
    )
    assert g == pytest.approx(m["mse_glossy_indirect"], rel=1e-9)
    assert pe["unattributed_glossy_indirect_unresolved"] == pytest.approx(
        pe["glossy_indirect_unresolved"].sum(), rel=1e-12
    )
    assert pe["diffuse_indirect"].sum() > 0 and pe["glossy_indirect"].sum() > 0
    write_evaluation(result, tmp_path / "eval")
    with np.load(tmp_path / "eval" / "probe_error.npz") as z:
        np.testing.assert_array_equal(z["diffuse_indirect"], pe["diffuse_indirect"])
        np.testing.assert_array_equal(z["pos_world"], np.asarray(lf.pos_world))
        assert str(z["format"]) == "probeplace.ProbeError/1"


@pytest.mark.parametrize("method", ["lightfield", "irradiance"])
def test_irradiance_weights_reproduce_the_shading(cornell_eval, method):
    """The weights the error is shared by are the shading's: blending each probe's irradiance with
    ``irradiance_weights`` gives ``shade_irradiance``'s value at random surface-ish points."""
    from probeplace._core import sample_bilinear
    from probeplace.probes import irradiance_weights, shade_irradiance

    scene, lf, _, _ = cornell_eval
    rng = np.random.default_rng(0)
    lo, hi = np.asarray(scene.bounds[0]), np.asarray(scene.bounds[1])
    pts = (lo + rng.uniform(0.02, 0.98, (200, 3)) * (hi - lo)).astype(np.float32)
    nrm = rng.normal(size=(200, 3)).astype(np.float32)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    pts, nrm = jnp.asarray(pts), jnp.asarray(nrm)
    e = np.asarray(shade_irradiance(lf, pts, nrm, method=method))
    ids, w = irradiance_weights(lf, pts, nrm, method=method)
    assert np.allclose(w.sum(axis=1), 1.0, atol=1e-5)  # float32 normalisation
    vals = np.asarray(
        jax.vmap(lambda p, n: jax.vmap(sample_bilinear, (0, None))(lf.irradiance[p], n))(
            np.maximum(ids, 0), nrm
        )
    )
    blend = np.sum(np.where(ids >= 0, w, 0.0)[..., None] * vals, axis=1)
    # float32: the shading divides by the weight total once, here each weight is divided first
    np.testing.assert_allclose(blend, e, rtol=1e-4, atol=1e-6 * float(np.abs(e).max()))
