"""What the report reads from a run record, its statistics over seeds and the words for its metric keys.

A run record is a finished run's ``metrics.json`` plus ``dir`` and ``evaluation`` (``_report.load_runs``):
its ``eval`` group read by ``evaluate.EvalMetrics.from_json`` (:func:`evaluation`), so the evaluation's
figures are read as typed fields (:func:`mse`, :func:`noise_floor`, :func:`black_mse`, ...), a figure an
older run lacks as None; the runner's own figures (``n_probes``, ``coverage``, ``timings``, ``memory``,
``bake_samples``) are read from the record. Each statistic is
written once here and used by both the charts (``_report_charts``) and the tables (``_report``):

* :func:`t_interval`: the mean and its Student-t confidence interval (95 %, n − 1 degrees of freedom,
  sample standard deviation with ddof = 1) — the spread of a cell's seeds, not of its pixels.
* :func:`log_t_interval`: the same in log space, mapped back (geometric mean, an interval that stays
  positive on a log axis): used for MSEs and MSE ratios, whose seed-to-seed spread is multiplicative.
* :func:`seed_paired_ratio`: :func:`log_t_interval` of method ÷ grid, one ratio per seed.

:data:`METRIC_WORDS` is the one mapping from metric keys to the words figures and tables print.

A run's failures and its coverage verdict are the runner's (``_run.failures``, ``placement.reaches_target``),
re-judged on every record by :func:`run_failures` so that older runs follow the current criteria.
:func:`load_scenes` gives each run's scene, loaded once per report (or why it could not be).
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from collections.abc import Callable

import numpy as np

from .._core import RunFiles
from ..evaluate import EVAL_COMPONENTS, METRIC_KEYS, EvalMetrics, metric_key

#: The image component whose MSE the report ranks by (its tables, time and memory charts).
PRIMARY = "glossy_indirect"
#: The components in the report's order: the primary first.
COMPONENTS = (PRIMARY, *(c for c in EVAL_COMPONENTS if c != PRIMARY))
LEVEL = 0.95

#: Component → its words; family → the words of its figure of a component, ``{}`` standing for those.
COMPONENT_WORDS = {
    "glossy_indirect": "glossy indirect",
    "diffuse_indirect": "diffuse indirect",
    "full": "full image",
}
FAMILY_WORDS = {
    "mse": "{} MSE",
    "noise_floor": "reference noise floor ({})",
    "mse_black": "black image (no indirect light)",
}

#: Metric key → the words a reader sees (axis labels, titles, table headers).
METRIC_WORDS = {
    **{
        key: text.format(COMPONENT_WORDS[c])
        for fam, text in FAMILY_WORDS.items()
        for c in EVAL_COMPONENTS
        if (key := metric_key(fam, c)) in METRIC_KEYS
    },
    "n_probes": "probes",
    "memory_bytes": "probe memory (KiB)",
    "place_bake_run_s": "placement + bake run time, JIT compilation excluded (s)",
    "shading_ms_per_frame": "shading per frame, compilation excluded (ms)",
    "uncovered": "uncovered share of the surface",
    "light_leak_pixels": "light-leak pixels",
    "light_leak_share": "light-leak share of judged pixels",
    "coverage": "surface coverage",
}


def words(key: str) -> str:
    """The words for a metric key (:data:`METRIC_WORDS`); an unlisted key is spelled with spaces."""
    return METRIC_WORDS.get(key, key.replace("_", " "))


def figure_words(family: str, component: str = PRIMARY) -> str:
    """The words for ``family``'s figure of ``component`` (``figure_words("mse")``: the primary MSE)."""
    return words(metric_key(family, component))


def t_interval(values, level: float = LEVEL) -> tuple[float, float, float]:
    """``(mean, lo, hi)``: the mean of ``values`` and its two-sided Student-t interval at ``level``
    (half-width t_{(1+level)/2, n−1} · s / √n, s with ddof = 1); ``(mean, nan, nan)`` for one value.

    Raises:
        ValueError: no value.
    """
    v = np.asarray(values, np.float64).reshape(-1)
    if not v.size:
        raise ValueError("t_interval needs at least one value")
    mean = float(v.mean())
    if v.size < 2:
        return mean, math.nan, math.nan
    from scipy import stats

    half = float(stats.t.ppf(0.5 + level / 2, v.size - 1) * v.std(ddof=1) / math.sqrt(v.size))
    return mean, mean - half, mean + half


def log_t_interval(values, level: float = LEVEL) -> tuple[float, float, float] | None:
    """Geometric mean of the positive ``values`` and :func:`t_interval` taken in log space, mapped back
    with exp; None when no value is positive (non-positive values have no logarithm and are dropped)."""
    logs = [math.log(x) for x in values if x > 0 and math.isfinite(x)]
    if not logs:
        return None
    return tuple(math.exp(x) for x in t_interval(logs, level))  # exp(nan) is nan: one value, no interval


def seed_paired_ratio(pairs: list[tuple[float, float]]) -> tuple[float, float, float] | None:
    """Geometric mean of ``method ÷ grid`` over seeds (each pair: one seed's two MSEs) with a 95 %
    Student-t interval in log space (:func:`log_t_interval`) — the seed-to-seed spread of placement, bake
    and reference noise together. ``(ratio, lo, hi)``; the interval is (nan, nan) with one seed."""
    return log_t_interval([m / g for m, g in pairs if m > 0 and g > 0])


def cells(runs: list[dict], x_fn: Callable, y_fn: Callable) -> dict:
    """label → sorted [(x, geometric mean of y, lo, hi, n runs)]: the runs of one label with equal
    ``x_fn(run)`` form a cell (its seeds and scene offsets), summarised by :func:`log_t_interval`."""
    by = defaultdict(list)
    for r in runs:
        x, y = x_fn(r), y_fn(r)
        if x is not None and y is not None:
            by[(r["label"], x)].append(y)
    out = defaultdict(list)
    for (lab, x), ys in sorted(by.items()):
        q = log_t_interval(ys)
        if q is not None:
            out[lab].append((x, *q, len(ys)))
    return dict(out)


def _num(v) -> float | None:
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) else None


def evaluation(r: dict) -> EvalMetrics | None:
    """The run's evaluation (``metrics.json``'s ``eval``, ``EvalMetrics.from_json``; ``load_runs`` reads
    it once into ``r["evaluation"]``); None for a run without one."""
    if "evaluation" in r:
        return r["evaluation"]
    return EvalMetrics.from_json(r["eval"]) if r.get("eval") else None


def _component_figure(r: dict, field: str, component: str) -> float | None:
    """Field ``field`` of the run's ``component`` record (None without an evaluation, or when missing or
    not finite)."""
    ev = evaluation(r)
    return None if ev is None else _num(getattr(ev.component(component), field))


def mse(r: dict, component: str = PRIMARY) -> float | None:
    """The MSE of the run's ``component`` image (None when missing or not finite)."""
    return _component_figure(r, "mse", component)


def top_pixel_share(r: dict, component: str = PRIMARY) -> float | None:
    """The largest pixel's share of the run's ``component`` squared error (None for a run written before
    the figure existed, or with no error)."""
    return _component_figure(r, "top_pixel_share", component)


def top_percent_share(r: dict, component: str = PRIMARY) -> float | None:
    """The share of the run's ``component`` squared error made by its 1 % of pixels with the largest (None
    for a run written before the figure existed, or with no error)."""
    return _component_figure(r, "top_percent_share", component)


def tail_index(r: dict, component: str = PRIMARY) -> float | None:
    """Hill's tail index of the run's ``component`` per-pixel squared error (``evaluate.tail_index``; None
    for a run written before the figure existed, or with no tail to measure)."""
    return _component_figure(r, "tail_index", component)


def noise_floor(r: dict, component: str = PRIMARY) -> float | None:
    """The reference's noise floor of the run's ``component`` (None when missing or not finite)."""
    return _component_figure(r, "noise_floor", component)


def black_mse(r: dict, component: str = PRIMARY) -> float | None:
    """MSE of a black image (no indirect light) for an indirect component: the evaluation's
    ``mse_black``, else the mean square of the saved reference image (older runs); None for a component
    without one (the full image)."""
    if metric_key("mse_black", component) not in METRIC_KEYS:
        return None
    v = _component_figure(r, "mse_black", component)
    if v is not None:
        return v
    exr = r["dir"] / RunFiles.eval_dir / RunFiles.images
    if not exr.exists():
        return None
    from ..render import load_exr

    ref = load_exr(exr).get(f"ref_{component}")
    return None if ref is None else float(np.mean(np.asarray(ref, np.float64) ** 2))


def run_s(r: dict) -> float | None:
    """Placement + bake run time without JIT compilation (``timings.place_bake_run_s``); for runs written
    before the compile/run split, their wall time ``place_bake_s`` (compilation included)."""
    t = r.get("timings") or {}
    return _num(t.get("place_bake_run_s", t.get("place_bake_s")))


def stage_run_s(r: dict, stage: str) -> float | None:
    """``<stage>_run_s``, else (older runs) the wall time ``<stage>_s``."""
    t = r.get("timings") or {}
    return _num(t.get(f"{stage}_run_s", t.get(f"{stage}_s")))


def compile_s(r: dict) -> float | None:
    """Placement + bake compile time; ``None`` for runs written before the split."""
    t = r.get("timings") or {}
    if "bake_compile_s" not in t and "place_compile_s" not in t:
        return None
    return float(t.get("place_compile_s", 0.0)) + float(t.get("bake_compile_s", 0.0))


def n_unsplit(runs: list[dict]) -> int:
    """Runs whose metrics.json predates the compile/run split (times include compilation)."""
    return sum("place_bake_run_s" not in (r.get("timings") or {}) for r in runs)


def shade_s(r: dict) -> float | None:
    """Probe shading seconds per frame, compilation excluded."""
    ev = evaluation(r)
    return None if ev is None else _num(ev.shading_s_per_frame)


def memory(r: dict) -> float | None:
    """Bytes of the run's real probes as stored (``metrics.memory.bytes_total``, written by run())."""
    return _num((r.get("memory") or {}).get("bytes_total"))


def leak_share(r: dict) -> float | None:
    """Share of the judged pixels flagged as light leak (``light_leak_pixels`` ÷
    ``light_leak_judged_pixels`` of the diffuse indirect; None for runs evaluated before the
    noise-relative definition)."""
    ev = evaluation(r)
    if ev is None:
        return None
    d = ev.diffuse_indirect
    n, judged = _num(d.light_leak_pixels), _num(d.light_leak_judged_pixels)
    return None if n is None or not judged else n / judged


def run_failures(r: dict) -> list[str]:
    """The run's failures judged now by the runner's criteria (``_run.failures``) — not the list stored
    in its metrics.json, which an older runner judged by older criteria."""
    from ._run import failures

    return failures(r)


def unresolved(r: dict) -> float | None:
    """Share of the evaluation's light-field rays the tracer could not resolve (the glossy indirect's
    ``unresolved_share``)."""
    ev = evaluation(r)
    return None if ev is None else _num(ev.glossy_indirect.unresolved_share)


def full_coverage(r: dict) -> bool | None:
    """Whether the run's coverage is full by ``placement.reaches_target`` (the tolerance of
    ``target_reached``); None when the run has no coverage."""
    from ..placement import reaches_target

    c = _num(r.get("coverage"))
    return None if c is None else reaches_target(c)


def median_run_s(rs: list[dict]) -> float | None:
    """Median placement + bake run time (:func:`run_s`) of a cell's runs; None when none has one."""
    t = [v for r in rs if (v := run_s(r)) is not None]
    return float(np.median(t)) if t else None


def count_cells(rs: list[dict]) -> dict:
    """label → {probe count: its runs} (runs with a positive, finite MSE: a geometric mean exists)."""
    out: dict = defaultdict(lambda: defaultdict(list))
    for r in rs:
        if (v := mse(r)) is not None and v > 0:
            out[r["label"]][r["n_probes"]].append(r)
    return out


def comparator() -> str:
    """The label every report table compares against: the first reference baseline of the placement
    registry (``placement.reference_methods``: the uniform grid)."""
    from ..placement import reference_methods

    return reference_methods()[0]


def grid_count(grid: list[dict]) -> int:
    """The grid's probe count the report compares at (its equal-count table, report.html's images): its
    measured count nearest (log) to the median of its counts (a count it really ran, so equal counts are
    exact)."""
    counts = sorted({r["n_probes"] for r in grid})
    med = float(np.median([r["n_probes"] for r in grid]))
    return min(counts, key=lambda c: (abs(math.log(c / med)), c))


def _placement_key(r: dict) -> tuple:
    """Runs that could share a placement: same scene, pose, seed and probe count."""
    return (r["scene"], tuple(r.get("translate_frac") or ()), r.get("rotate_deg"), r["seed"], r["n_probes"])


def placement_twins(runs: list[dict], labels: list[str]) -> dict:
    """run name → the label of an earlier method (in ``labels`` order) whose run on the same scene, pose,
    seed and probe count placed bit-identical probes (the active positions of ``probes.json``, in any
    order) — e.g. the LOD grid at a count where it is the uniform grid. Runs without a twin are absent."""
    from .._core import load_probe_set

    def positions(r):
        probes, _ = load_probe_set(r["dir"] / RunFiles.probes)
        p = np.asarray(probes.pos_world)[np.asarray(probes.active)]
        return p[np.lexsort(p.T[::-1])]

    by = defaultdict(list)
    for r in runs:
        if (r["dir"] / RunFiles.probes).is_file():
            by[_placement_key(r)].append(r)
    twins = {}
    for group_ in by.values():
        if len({r["label"] for r in group_}) < 2:
            continue
        group_.sort(key=lambda r: labels.index(r["label"]))
        pos = [positions(r) for r in group_]
        for i, r in enumerate(group_):
            for j in range(i):
                if group_[j]["label"] != r["label"] and np.array_equal(pos[i], pos[j]):
                    twins[r["run"]] = twins.get(group_[j]["run"], group_[j]["label"])
                    break
    return twins


def pareto_front(points: list) -> list[int]:
    """Indices of the points not dominated in (x, y), both minimised; sorted by x."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def group(runs: list[dict]) -> dict:
    """(scene, label) → runs."""
    g = defaultdict(list)
    for r in runs:
        g[(r["scene"], r["label"])].append(r)
    return g


POSES = ("base", "translated", "rotated", "translated+rotated")


def pose(r: dict) -> str:
    """How the run's scene was perturbed against the grid: base, translated, rotated, or both."""
    moved = any(float(x) != 0.0 for x in r.get("translate_frac") or ())
    turned = float(r.get("rotate_deg") or 0.0) != 0.0
    return {(False, False): "base", (True, False): "translated", (False, True): "rotated"}.get(
        (moved, turned), "translated+rotated"
    )


def load_scenes(runs: list[dict]) -> dict:
    """run name → its scene (``config.yaml``: name, sidecar, overrides, pose), each distinct scene loaded
    once per report; a scene that cannot be loaded (an external file missing from the search path) maps
    to the one-line reason instead, so the report is still written and says why a view is missing."""
    from ._run import load_experiment_scene
    from ._schema import config_to_dict, load_config_yaml, to_config

    by_key, out = {}, {}
    for r in runs:
        cfg = to_config(load_config_yaml(r["dir"] / RunFiles.config))
        key = json.dumps(config_to_dict(cfg)["scene"], sort_keys=True)
        if key not in by_key:
            try:
                by_key[key] = load_experiment_scene(cfg.scene)
            except Exception as e:  # any loader failure: the report describes it rather than stopping
                first = (str(e).splitlines() or [type(e).__name__])[0]
                by_key[key] = f"scene {cfg.scene.name!r} could not be loaded: {first}"
        out[r["run"]] = by_key[key]
    return out
