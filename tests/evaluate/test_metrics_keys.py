"""The evaluation's typed metrics (``evaluate/_metrics.py``) and the metrics.json they write.

Oracles: (a) docs/evaluate.md's "metrics.json" table, which must list exactly the keys ``to_json`` writes;
(b) the dict ``score`` built by hand before the typed record existed (commit 35686bf), rebuilt here
from the same steps' results by that code's rules (:func:`_legacy_metrics`, copied from it and reading
only public building blocks): ``to_json`` must give it key for key, in the same order, with the same
values and nesting, so that a run's ``metrics.json`` is byte-identical up to the keys added since, which
follow its keys and have their own oracle there; (c) the round trip
``from_json(to_json(m)) == m`` on that real evaluation, also through JSON text; (d) runs written before a
figure existed read back with that figure None.
"""

from __future__ import annotations

import dataclasses
import json
import math
import pickle
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import probeplace
from probeplace._core import json_number, scene_box
from probeplace.evaluate import (
    EVAL_COMPONENTS,
    METRIC_KEYS,
    EvalMetrics,
    EvalResult,
    bootstrap_ci,
    glossy_terms,
    hit_agreement,
    memory_bytes,
    metric_key,
    relative_mse,
    score,
)
from probeplace.evaluate._decompose import light_leak, pixel_means
from probeplace.evaluate._samples import CountChoice, Pilot
from probeplace.probes import TraceStatus
from tests.evaluate.conftest import evaluation_steps

DOC = Path(__file__).resolve().parents[2] / "docs" / "evaluate.md"


def _doc_tables() -> list[list[str]]:
    """The keys of each table under docs/evaluate.md's "## metrics.json": the backquoted names in each
    row's first cell."""
    section = DOC.read_text().split("\n## metrics.json\n", 1)[1].split("\n## ", 1)[0]
    tables, rows = [], None
    for line in section.splitlines():
        if line.startswith("| key | meaning |"):
            rows = []
            tables.append(rows)
        elif line.startswith("| `") and rows is not None:
            rows += re.findall(r"`([^`]+)`", line.split("|")[1])
        elif not line.startswith("|"):
            rows = None
    return tables


def test_the_docs_list_every_key_once():
    """docs/evaluate.md's table is the typed record's ``to_json`` keys; the keys written beside them
    (its second table) are not evaluation metrics."""
    ours, beside = _doc_tables()
    assert len(ours) == len(set(ours)), sorted(k for k in ours if ours.count(k) > 1)
    assert set(ours) == set(EvalMetrics().to_json()), set(ours) ^ set(EvalMetrics().to_json())
    assert tuple(EvalMetrics().to_json()) == METRIC_KEYS
    assert set(beside) == {"error_png_vmax", "bake_samples"} and not set(beside) & set(METRIC_KEYS)


# --- the dict score() built before the typed record (commit 35686bf), from the steps' results ---------


def _mse(a, b) -> float:
    return float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))


def _sq_px(a, b) -> np.ndarray:
    d = np.asarray(a, np.float64) - np.asarray(b, np.float64)
    return np.mean(d * d, axis=-1).reshape(-1)


def _legacy_samples(config, choices: dict, metrics: dict) -> dict:
    comps = ("diffuse_indirect", "glossy_indirect")
    per = lambda f: {c: json_number(f(choices[c])) for c in comps}
    pilot = lambda f: per(lambda ch: None if ch.pilot is None else f(ch.pilot))
    final = {}
    for c in comps:
        floor, black = metrics[f"noise_floor_{c}"], metrics[f"mse_black_{c}"]
        final[c] = floor / black if black > 0 else (0.0 if floor <= 0 else math.inf)
    auto = any(ch.chosen_by == "target" for ch in choices.values())
    return {
        "noise_target": config.noise_target,
        "pilot_spp": config.pilot_spp if auto else None,
        "max_spp": config.max_spp if auto else None,
        "reference_spp": choices["diffuse_indirect"].spp,
        "reference_chosen_by": choices["diffuse_indirect"].chosen_by,
        "glossy_ref_spp": choices["glossy_indirect"].spp,
        "glossy_ref_chosen_by": choices["glossy_indirect"].chosen_by,
        "pilot_floor": pilot(lambda p: p.floor),
        "pilot_floor_se": pilot(lambda p: p.floor_se),
        "pilot_black": pilot(lambda p: p.black),
        "pilot_floor_over_black": pilot(lambda p: p.floor / p.black if p.black > 0 else None),
        "pilot_s": pilot(lambda p: p.seconds),
        "predicted_floor_over_black": per(lambda ch: ch.predicted),
        "floor_over_black": {c: json_number(v) for c, v in final.items()},
        "target_met": all(v <= config.noise_target for v in final.values()),
    }


def _legacy_metrics(scene, lf, view, config, seed, ref, prim, crn, shading, perfect, counts) -> dict:
    """``score``'s metrics dict as commit 35686bf wrote it, key by key, then the keys added since."""
    W, H, S = prim.width, prim.height, prim.spp
    ref_img, ref_var = ref.images, ref.variance
    w_gl = prim.w_glossy
    img = lambda v: pixel_means(v, H * W, S).reshape(H, W, *v.shape[1:])
    probe_g = img(w_gl * shading.glossy)
    crn_ref_g = img(w_gl * crn.radiance)
    perfect_g = img(w_gl * perfect.radiance)
    view_indep_g = img(w_gl * crn.diffuse_at_hit)
    floor_g = float(np.mean((w_gl**2 * crn.var_of_mean).reshape(H * W, S, 3).sum(axis=1) / S**2))
    probe_d = img(prim.rho_d * shading.irradiance / np.pi)
    probe_full = ref_img["emission"] + ref_img["direct"] + probe_d + probe_g
    hit_px = img(prim.valid[:, None].astype(np.float64))[..., 0] > 0
    boot = lambda v: bootstrap_ci(v, n_resamples=config.bootstrap_resamples, seed=0)
    rel = lambda a, b: relative_mse(a, b, eps=config.relmse_eps)

    leak = light_leak(
        ref_img["diffuse_indirect"], ref_var["diffuse_indirect"], probe_d, hit_px, sigmas=config.leak_sigmas
    )
    n_leak, judged = int(leak["flagged"].sum()), int(leak["judged"].sum())

    st = shading.status
    gl = st >= 0
    n_gl = int(gl.sum())
    lo, hi = scene_box(scene)
    terms = glossy_terms(prim.w_glossy, shading.glossy, crn.radiance, perfect.radiance, st, S)
    agree, n_agree = hit_agreement(
        shading.t, perfect.t_exact, st, rtol=config.agreement_rtol, atol=1e-4 * float(np.linalg.norm(hi - lo))
    )
    n_exact = int(np.sum(gl & np.isfinite(perfect.t_exact)))
    seen_gl = gl & shading.origin_seen
    n_seen = int(seen_gl.sum())
    names = {int(s): s.label for s in TraceStatus}

    metrics = {
        "scene": scene.name,
        "view": view,
        "width": prim.width,
        "height": prim.height,
        "spp": config.spp,
        "glossy_spp": prim.spp,
        "glossy_ref_spp": config.glossy_ref_spp,
        "max_depth": config.max_depth,
        "shading": config.shading,
        "trace_hierarchy": config.trace.hierarchy,
        "glossy_filter": config.glossy_filter,
        "glossy_lod_bias": config.glossy_lod_bias,
        "seed": seed,
        "n_probes": int(np.sum(np.asarray(lf.active))),
        "n_probes_usable": int(np.sum(np.asarray(lf.active) & ~np.asarray(lf.inside))),
        "probe_first_hit_lobes": None if lf.bake is None else lf.bake.first_hit_lobes,
        "mse_glossy_indirect": _mse(probe_g, crn_ref_g),
        "noise_floor_glossy_indirect": floor_g,
        "mse_glossy_indirect_no_crn": _mse(probe_g, ref_img["glossy_indirect"]),
        "mse_diffuse_indirect": _mse(probe_d, ref_img["diffuse_indirect"]),
        "mse_black_glossy_indirect": _mse(np.zeros_like(crn_ref_g), crn_ref_g),
        "mse_black_diffuse_indirect": _mse(
            np.zeros_like(ref_img["diffuse_indirect"]), ref_img["diffuse_indirect"]
        ),
        "noise_floor_diffuse_indirect": float(np.mean(ref_var["diffuse_indirect"])),
        "mse_full": _mse(probe_full, ref_img["full"]),
        "noise_floor_full": float(np.mean(ref_var["diffuse_indirect"] + ref_var["glossy_indirect"])),
        "light_leak_energy": leak["energy"],
        "light_leak_pixels": n_leak,
        "light_leak_judged_pixels": judged,
        "light_leak_share": n_leak / judged if judged else None,
        "light_leak_sigmas": float(config.leak_sigmas),
        "glossy_rays": n_gl,
        "unresolved_share": float(np.mean(st[gl] == TraceStatus.UNRESOLVED)) if n_gl else 0.0,
        "origin_seen_share": n_seen / n_gl if n_gl else 0.0,
        "unresolved_seen_share": float(np.mean(st[seen_gl] == TraceStatus.UNRESOLVED)) if n_seen else None,
        "mse_glossy_perfect_trace": terms["mse_perfect_trace"],
        "mse_glossy_view_dependence": _mse(view_indep_g, crn_ref_g),
        "mse_glossy_trace_share": terms["trace_share"],
        "trace_excess": terms["trace_excess"],
        "mse_glossy_by_status": terms["by_status"],
        "mse_glossy_resolved_only": terms["resolved_only"],
        "glossy_status_share": {
            name: (float(np.mean(st[gl] == k)) if n_gl else 0.0) for k, name in names.items()
        },
        "glossy_hit_agreement": agree,
        "glossy_hit_agreement_rays": n_agree,
        "perfect_trace_fallbacks": int(np.sum(perfect.fallback)),
        "perfect_trace_fallback_share": float(np.sum(perfect.fallback) / n_exact) if n_exact else 0.0,
        "relmse_glossy_indirect": rel(probe_g, crn_ref_g),
        "relmse_glossy_perfect_trace": rel(perfect_g, crn_ref_g),
        "relmse_black_glossy_indirect": rel(np.zeros_like(crn_ref_g), crn_ref_g),
        "ci95_mse_glossy_indirect": boot(terms["sq_px"]),
        "ci95_mse_glossy_perfect_trace": boot(terms["sq_px_perfect"]),
        "ci95_mse_glossy_trace_share": boot(terms["sq_px"] - terms["sq_px_perfect"]),
        "relmse_diffuse_indirect": rel(probe_d, ref_img["diffuse_indirect"]),
        "relmse_black_diffuse_indirect": rel(np.zeros_like(probe_d), ref_img["diffuse_indirect"]),
        "relmse_full": rel(probe_full, ref_img["full"]),
        "ci95_mse_diffuse_indirect": boot(_sq_px(probe_d, ref_img["diffuse_indirect"])),
        "ci95_mse_full": boot(_sq_px(probe_full, ref_img["full"])),
        "bootstrap_resamples": config.bootstrap_resamples,
        "relmse_eps": config.relmse_eps,
        "shading_s_per_frame": shading.seconds_per_frame,
        "shading_compile_s": shading.compile_seconds,
        "reference_s": ref.seconds,
        "memory_bytes": memory_bytes(lf, config.trace.subdivide),
    }
    metrics["samples"] = _legacy_samples(config, counts, metrics)
    # Added since that commit, after its keys (``_JSON_ORDER``), component by component: the largest
    # pixel's share of the component's summed per-pixel squared error, and the share of its 1 % of pixels
    # with the largest (one at least), by a full sort.
    share = lambda v: float(np.max(v) / np.sum(v)) if np.sum(v) > 0 else None
    top = lambda v: (
        float(np.sort(v, axis=None)[::-1][: max(1, v.size // 100)].sum() / v.sum()) if v.sum() > 0 else None
    )

    # Hill's tail index from the same 1 % (k of them) over the next largest, by a full sort of the positive.
    def hill(v):
        pos = np.sort(v[v > 0])[::-1]
        k = max(1, v.size // 100)
        if pos.size <= k or np.mean(np.log(pos[:k] / pos[k])) <= 0:
            return None
        return float(1.0 / np.mean(np.log(pos[:k] / pos[k])))

    # The converged image's MSE: per pixel and channel the mean of d_s·d_t over the ordered pairs of two
    # different samples s ≠ t, d_s = w_s (L_probe,s − L_ref,s), by the outer product less its diagonal.
    d = (prim.w_glossy * (shading.glossy - crn.radiance)).reshape(-1, S, 3)
    pairs = np.einsum("psc,ptc->pcst", d, d)
    conv = (pairs.sum(axis=(2, 3)) - np.trace(pairs, axis1=2, axis2=3)).mean(axis=1) / (S * (S - 1))
    for c, sq in (
        ("diffuse_indirect", _sq_px(probe_d, ref_img["diffuse_indirect"])),
        ("glossy_indirect", terms["sq_px"]),
        ("full", _sq_px(probe_full, ref_img["full"])),
    ):
        metrics[f"top_pixel_share_{c}"] = share(sq)
        metrics[f"top_percent_share_{c}"] = top(sq)
        metrics[f"tail_index_{c}"] = hill(sq)
        if c == "glossy_indirect":  # the glossy record's own figure, after its component figures
            metrics["mse_glossy_converged"] = float(np.mean(conv))
            metrics["ci95_mse_glossy_converged"] = boot(conv)
    return metrics


@pytest.fixture(scope="module")
def steps(cornell):
    """The evaluation's steps on the shared tiny Cornell box at fixed counts (as ``evaluate`` runs them)."""
    scene, lf, caster, base = cornell
    config = dataclasses.replace(base, spp=8, glossy_ref_spp=2)
    return (scene, lf, "front", config, *evaluation_steps(scene, lf, caster, config))


#: Counts as ``evaluate`` passes them: both fixed, and one chosen from a (made-up) pilot.
PILOT = Pilot(spp=4, floor=2e-4, floor_se=3e-5, black=1e-3, seconds=0.25)
COUNTS = {
    "fixed": {"diffuse_indirect": CountChoice(8, "fixed"), "glossy_indirect": CountChoice(2, "fixed")},
    "target": {
        "diffuse_indirect": CountChoice(8, "target", PILOT, 0.04),
        "glossy_indirect": CountChoice(2, "fixed"),
    },
}


@pytest.mark.parametrize("counts", list(COUNTS))
def test_to_json_is_the_dict_score_wrote_before(steps, counts):
    """``to_json`` of ``score``'s typed record is the dict the hand-written code built: the same keys in
    the same order, the same values and nesting (lists, not tuples), so the same metrics.json text."""
    result = score(*steps, counts=COUNTS[counts])
    want = _legacy_metrics(*steps, COUNTS[counts])
    got = result.metrics
    assert list(got) == list(want) == list(METRIC_KEYS)
    # The converged MSE's oracle sums its pairs in another order: float64 rounding apart (ulps of the
    # pairs' sum, far below 1e-9 of it even where the pairs cancel a thousandfold), the same figures.
    got, want = dict(got), dict(want)
    for k in ("mse_glossy_converged", "ci95_mse_glossy_converged"):
        assert got.pop(k) == pytest.approx(want.pop(k), rel=1e-9), k
    assert got == want
    assert json.dumps(got, indent=1, allow_nan=False) == json.dumps(want, indent=1, allow_nan=False)
    for c in EVAL_COMPONENTS:  # the key rule, on the record's own fields
        assert got[metric_key("mse", c)] == result.scores.component(c).mse
        assert got[metric_key("ci95_mse", c)] == list(result.scores.component(c).ci95_mse)


def test_from_json_reads_back_what_to_json_wrote(steps):
    """The round trip on a real evaluation, directly and through metrics.json's text; ``EvalResult``'s
    ``metrics`` is ``to_json`` and a key added with ``dataclasses.replace`` (``probeplace evaluate``'s
    ``bake_samples``) is kept beside the scores, last."""
    result = score(*steps, counts=COUNTS["target"])
    m = result.scores
    assert EvalMetrics.from_json(m.to_json()) == m
    assert EvalMetrics.from_json(json.loads(json.dumps(m.to_json()))) == m
    assert result.metrics == m.to_json()
    added = dataclasses.replace(result, metrics={**result.metrics, "bake_samples": {"spp": 4}})
    assert added.scores == m and added.extra == {"bake_samples": {"spp": 4}}
    assert list(added.metrics) == [*METRIC_KEYS, "bake_samples"]
    assert added.images is result.images and added.probe_error is result.probe_error
    assert dataclasses.replace(added, images={}).metrics == added.metrics


def test_from_json_tolerates_older_and_foreign_keys():
    """A run written before a figure existed reads back with it None (the report's older runs); keys that
    are not the evaluation's are ignored; what is not a dict is refused."""
    old = {"mse_glossy_indirect": 2.0, "noise_floor_glossy_indirect": 1.0, "ci95_mse_full": [1.0, 3.0]}
    old |= {"samples": {"reference_chosen_by": "fixed"}, "backend": "jax", "error_png_vmax": {"full": 1.0}}
    m = EvalMetrics.from_json(old)
    assert (m.glossy_indirect.mse, m.glossy_indirect.noise_floor) == (2.0, 1.0)
    assert m.full.ci95_mse == (1.0, 3.0) and m.diffuse_indirect.mse is None
    assert m.diffuse_indirect.light_leak_pixels is None and m.settings.view is None
    assert m.samples.reference_chosen_by == "fixed" and m.samples.target_met is None
    assert EvalMetrics.from_json({}) == EvalMetrics()
    with pytest.raises(TypeError):  # the message is the test suite's type checker's (jaxtyping) here
        EvalMetrics.from_json([1, 2])
    with pytest.raises(KeyError, match="no image component 'direct'"):
        m.component("direct")


def test_a_result_needs_typed_scores():
    with pytest.raises(TypeError):
        EvalResult(scores={}, images={})
    with pytest.raises(TypeError, match="images are required"):
        EvalResult(scores=EvalMetrics())


ARCH = Path(__file__).resolve().parents[2] / "docs" / "architecture.md"


def test_the_documented_metric_is_one_edit(steps, tmp_path):
    """docs/architecture.md's "adding a metric" field, pasted into ``ComponentScores`` in a copy of the
    package and nothing else, is measured by ``score`` on every image component and written to metrics.json
    under ``<field>_<component>``; its value is checked against the result's own images (float32, hence the
    tolerance) and it reads back through ``from_json``. The steps' results travel to the copy pickled."""
    (block,) = [
        b
        for b in re.findall(r"```python\n(.*?)```", ARCH.read_text(encoding="utf-8"), re.S)
        if "measured(" in b
    ]
    field_src = "\n".join(line for line in block.splitlines() if not line.startswith("#"))
    name = re.search(r"^\s+(\w+):", field_src, re.M).group(1)
    copy = tmp_path / "probeplace"
    shutil.copytree(
        Path(probeplace.__file__).parent, copy, ignore=shutil.ignore_patterns("__pycache__", "_vendor")
    )
    metrics_py = copy / "evaluate" / "_metrics.py"
    text = metrics_py.read_text(encoding="utf-8")
    anchor = "\n\n@dataclasses.dataclass(frozen=True)\nclass IndirectScores(ComponentScores):"
    assert text.count(anchor) == 1
    metrics_py.write_text(text.replace(anchor, "\n" + field_src.rstrip() + "\n" + anchor), encoding="utf-8")
    (tmp_path / "steps.pkl").write_bytes(pickle.dumps(steps))
    check = textwrap.dedent(
        f"""
        import pickle
        import numpy as np
        import probeplace
        assert probeplace.__file__.startswith({str(tmp_path)!r}), probeplace.__file__
        from probeplace.evaluate import EVAL_COMPONENTS, METRIC_KEYS, EvalMetrics, score
        steps = pickle.loads(open({str(tmp_path / "steps.pkl")!r}, "rb").read())
        result = score(*steps)
        m = result.metrics
        for c in EVAL_COMPONENTS:
            key = {name!r} + "_" + c
            assert key in METRIC_KEYS and key in m, key
            d = np.asarray(result.images["probe_" + c], np.float64) - result.images["ref_" + c]
            want = float(np.sqrt(np.mean(d * d, axis=-1).max()))
            assert want > 0 and abs(m[key] - want) <= 1e-3 * want, (key, m[key], want)
        keys, new = list(m), {name!r}
        assert [k for k in keys if not k.startswith(new)] == [k for k in METRIC_KEYS if not k.startswith(new)]
        assert min(i for i, k in enumerate(keys) if k.startswith(new)) > keys.index("samples")
        assert EvalMetrics.from_json(m) == result.scores
        print("ok")
        """
    )
    env = {"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin:/bin", "JAX_PLATFORMS": "cpu"}
    done = subprocess.run([sys.executable, "-c", check], capture_output=True, text=True, env=env, timeout=300)
    assert done.stdout.strip() == "ok", done.stderr[-3000:]
