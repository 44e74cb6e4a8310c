"""Charts and a Markdown report redrawn from the saved files of an experiment (``experiments/report.py``).

Reads only finished run folders (``DONE``): ``metrics.json``, ``config.yaml``, ``probes.json`` and
``eval/images.exr``. Writes ``<experiment dir>/report/`` atomically: ``report.md``, ``mse_vs_count.png``,
``mse_vs_time.png`` (placement + bake, and shading per frame, Pareto front marked), ``memory_vs_mse.png``,
``error_images.png`` (one colour scale), ``top_views/<run>.png`` (a top and a side view of each probe
set) and, with several seeds or scene offsets, the stability tables; then ``report.html``, the same
report in one self-contained page with a 3D view of each scene's placements and their images
(``_report_html``). The figures are built in ``_report_charts``, the statistics and the words for metric
keys live in ``_report_data``. Each scene is loaded once per report (``_report_data.load_scenes``); one
that cannot be loaded is named in one line where its views would be.

Several runs of one method at one probe count (seeds, scene offsets) are one *cell*: charts draw its
geometric mean with a 95 % Student-t interval in log space as an error bar, and the tables print the
same numbers. Equal-count tables compare runs at exactly the same probe count (exact budgets); the
equal-memory tables compare runs holding equal bytes of probe data (``metrics.memory.bytes_total``),
else each method's run nearest to the grid's memory, with the bytes shown. The equal-time and
equal-quality tables compare cells too (a method's runs at one count: median time, geometric-mean MSE)
against the grid's cell at its count, so the grid is 1.00 × itself. A method whose probes are
bit-identical to an earlier method's on the same seed, pose and count (``probes.json``) is named
``method (= other)`` in the tables. Failures are re-judged by the runner's current criteria
(``_run.failures``); the stability tables explain them and show the unresolved-ray share apart.

Every time axis and the equal-time tables use run time *without JIT compilation*: ``place_bake_run_s``
from ``metrics.json`` (``experiment._run``: the first run of a sweep pays the compilation the later ones
reuse, which would otherwise decide the equal-time ranking and the Pareto front) and the evaluation's
``shading_s_per_frame`` (median of repeats after a compile run). Runs written before the split (no
``place_bake_run_s``) fall back to ``place_bake_s``, compilation included, and the report says how many.
"""

from __future__ import annotations

import json
import math
import os
import shutil
from pathlib import Path

import numpy as np

from .._core import RunFiles
from ._report_charts import (
    colours,
    fig_errors,
    fig_memory,
    fig_mse_vs_count,
    fig_mse_vs_time,
    fig_probe_views,
    fig_stability,
    save_figure,
)
from ._report_data import (
    POSES,
    PRIMARY,
    black_mse,
    cells,
    comparator,
    compile_s,
    count_cells,
    evaluation,
    figure_words,
    full_coverage,
    grid_count,
    group,
    leak_share,
    load_scenes,
    log_t_interval,
    median_run_s,
    memory,
    mse,
    n_unsplit,
    noise_floor,
    pareto_front,
    placement_twins,
    pose,
    run_failures,
    seed_paired_ratio,
    shade_s,
    stage_run_s,
    tail_index,
    top_percent_share,
    top_pixel_share,
    unresolved,
)
from ._report_html import write_report_html
from ._results import iter_runs

__all__ = ["load_runs", "make_report", "pareto_front", "seed_paired_ratio"]


def load_runs(exp_dir: str | os.PathLike) -> list[dict]:
    """One record per finished run: its metrics plus ``dir`` (Path) and ``evaluation``: its ``eval``
    group as an ``evaluate.EvalMetrics`` (None for a run without one; ``_report_data.evaluation``)."""
    runs = []
    for d in iter_runs(exp_dir):
        m = json.loads((d / RunFiles.metrics).read_text())
        m["dir"] = d
        m["evaluation"] = evaluation(m)
        runs.append(m)
    return runs


def _labels(runs: list[dict]) -> list[str]:
    """Run labels: the reference baselines first (placement registry order), then alphabetical."""
    from ..placement import reference_methods

    first = {m: i for i, m in enumerate(reference_methods())}
    return sorted({r["label"] for r in runs}, key=lambda s: (first.get(s, len(first)), s))


def _fmt(v, spec=".3g") -> str:
    if v is None:
        return "—"
    if isinstance(v, float) and not math.isfinite(v):
        return "—"
    return format(v, spec) if isinstance(v, int | float) and not isinstance(v, bool) else str(v)


def _coverage(r: dict) -> str:
    """The run's coverage to 4 decimals; a coverage short of full (:func:`full_coverage`) that would
    print as 1.0000 is written as 1 − its shortfall, so the table never shows 1.0000 beside a failure."""
    c, full = r.get("coverage"), full_coverage(r)
    if full is None:
        return "—"
    if not full and f"{c:.4f}" == "1.0000":
        return f"1 − {1.0 - c:.1e}"
    return f"{c:.4f}"


def _method(lab: str, runs: list[dict], twins: dict) -> str:
    """The method's name in a table row, with ``(= other)`` when its placement in every run of the row is
    bit-identical to another method's on the same seed (``(= other on k of n runs)`` when in some)."""
    same = [twins[r["run"]] for r in runs if r["run"] in twins]
    if not same:
        return lab
    other = max(set(same), key=same.count)
    k = same.count(other)
    return f"{lab} (= {other})" if k == len(runs) else f"{lab} (= {other} on {k} of {len(runs)} runs)"


def _interp_log(x0: float, pts: list) -> float | None:
    """y at x0 by linear interpolation in log-log over sorted (x, y); None outside the measured range."""
    pts = sorted(p for p in pts if p[0] > 0 and p[1] > 0)
    if not pts:
        return None
    xs, ys = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    lx = math.log(x0)
    if lx < xs[0] - 1e-12 or lx > xs[-1] + 1e-12:
        return None
    return float(np.exp(np.interp(lx, xs, ys)))


def _unsplit_note(runs: list[dict]) -> list[str]:
    """A line saying how many runs' times include JIT compilation (written before the split)."""
    n = n_unsplit(runs)
    if not n:
        return []
    return [
        f"_{n} of {len(runs)} runs predate the compile/run split (no `place_bake_run_s` in their "
        "metrics.json): their times are wall times, JIT compilation included._",
        "",
    ]


def _ci(q: tuple | None, spec: str = ".3g") -> str:
    """``mean [lo, hi]`` of a (mean, lo, hi) triple; ``mean`` alone when the interval is unknown."""
    if q is None:
        return "—"
    if not (math.isfinite(q[1]) and math.isfinite(q[2])):
        return format(q[0], spec)
    return f"{q[0]:{spec}} [{q[1]:{spec}}, {q[2]:{spec}}]"


def _leak(r: dict) -> str:
    """Light-leak pixels and their share of the judged pixels (the diffuse indirect's ``light_leak_*``)."""
    share = leak_share(r)
    if share is None:
        return "—"
    return f"{evaluation(r).diffuse_indirect.light_leak_pixels} ({share:.2%})"


def _all_runs_table(runs: list[dict], labels: list[str]) -> list[str]:
    """The "All runs" section: one row per run with its times, errors, memory and failures."""
    md = ["## All runs", ""]
    md += [
        "Place s and bake s are run times without JIT compilation; compile s is what placement and bake "
        "spent compiling (the first run of a process pays it for every later run of the same shapes); "
        "shading ms/frame excludes its compile run. Light leak: pixels where the probes' diffuse "
        "indirect exceeds the reference by more than 4 of the reference's own standard errors, and their "
        "share of the pixels whose standard error is known (docs/evaluate.md). One pixel: the largest "
        f"pixel's share of the {figure_words('mse')}; near 100 %, that MSE is one pixel's (a highlight no "
        "probe holds, say) and says little about the method. Top 1 %: the share of the 1 % of pixels "
        "with the largest error; the rest of the MSE, its bulk, is what repeats between seeds (on Sponza "
        "the top 1 % made 62-92 % of the glossy MSE at 128 probes, experiments/README.md §2). Tail α: "
        "Hill's tail index of the per-pixel error, from that 1 %; below 2 the error has no finite variance "
        "over the pixels sampled, so the MSE's interval over pixels understates how far it moves between "
        "seeds (Sponza's glossy error: 0.7-1.5).",
        "",
        *_unsplit_note(runs),
    ]
    md += [
        f"| run | probes | coverage | place s | bake s | compile s | {figure_words('mse')} "
        f"| {figure_words('mse', 'diffuse_indirect')} | {figure_words('mse', 'full')} "
        f"| {figure_words('noise_floor')} | one pixel | top 1 % | tail α "
        "| shading ms/frame | memory KiB | unresolved | light leak px (share) | failures |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for r in sorted(runs, key=lambda r: (r["scene"], labels.index(r["label"]), r["n_probes"], r["seed"])):
        mem = memory(r)
        md.append(
            f"| {r['run']} | {r['n_probes']} | {_coverage(r)} "
            f"| {_fmt(stage_run_s(r, 'place'), '.1f')} | {_fmt(stage_run_s(r, 'bake'), '.1f')} "
            f"| {_fmt(compile_s(r), '.1f')} | {_fmt(mse(r))} | {_fmt(mse(r, 'diffuse_indirect'))} "
            f"| {_fmt(mse(r, 'full'))} | {_fmt(noise_floor(r))} | {_fmt(top_pixel_share(r), '.0%')} "
            f"| {_fmt(top_percent_share(r), '.0%')} | {_fmt(tail_index(r), '.2f')} "
            f"| {_fmt(None if shade_s(r) is None else 1e3 * shade_s(r), '.2f')} "
            f"| {_fmt(None if mem is None else mem / 1024, '.1f')} "
            f"| {_fmt(unresolved(r), '.1%')} | {_leak(r)} "
            f"| {', '.join(run_failures(r)) or 'none'} |"
        )
    return md


def _equal_count_table(rs, labels, scene, g_count: int, g_mse: float, twins: dict) -> list[str]:
    """Each method's MSE at exactly the grid's probe count (geometric mean over its runs there, 95 %
    t-interval); a method with no run at that count: log-log interpolated between its counts, else its
    nearest count, and the row says so."""
    md = ["", f"## {scene}: equal probe count ({g_count} probes, the grid's count)", ""]
    black = [v for r in rs if (v := black_mse(r)) is not None]
    if black:
        b = float(np.median(black))
        md += [
            f"A black image (no indirect light) scores {b:.3g} here (÷ grid {b / g_mse:.2f}): a method "
            "above it adds more wrong light than it recovers.",
            "",
        ]
    md += [
        f"| method | {figure_words('mse')} at that count [95 % t-interval over runs] | ÷ grid | how |",
        "|---|---:|---:|---|",
    ]
    by = cells(rs, lambda r: r["n_probes"], mse)
    for lab in labels:
        cell = by.get(lab)
        if not cell:
            continue
        exact = [c for c in cell if c[0] == g_count]
        at = [r for r in rs if r["label"] == lab and r["n_probes"] == g_count]
        if exact:
            q, how = exact[0][1:4], f"measured at exactly {g_count} ({exact[0][4]} runs)"
        else:
            v, how = _interp_log(float(g_count), [(c[0], c[1]) for c in cell]), "interpolated (log-log)"
            if v is None:
                near = min(cell, key=lambda c: abs(math.log(c[0] / g_count)))
                v, how = near[1], f"nearest count measured: {near[0]}"
            q = (v, math.nan, math.nan)
        md.append(f"| {_method(lab, at, twins)} | {_ci(q)} | {_fmt(q[0] / g_mse, '.2f')} | {how} |")
    return md


def _memory_tiers(rs: list[dict]) -> tuple[list[float], bool]:
    """The memories (bytes) to compare at: every exact memory that two or more methods share (``True``),
    else the grid's median memory (or all runs' median without a grid) — compared at nearest (``False``)."""
    by_bytes: dict[float, set] = {}
    for r in rs:
        if (b := memory(r)) is not None:
            by_bytes.setdefault(b, set()).add(r["label"])
    shared = sorted(b for b, labs in by_bytes.items() if len(labs) > 1)
    if shared:
        return shared, True
    ref = [memory(r) for r in rs if r["label"] == comparator() and memory(r) is not None] or list(by_bytes)
    return ([float(np.median(ref))] if ref else []), False


def _equal_memory_table(rs, labels, scene, twins: dict) -> list[str]:
    """Each method at equal bytes of probe data: runs with exactly that memory (geometric mean over them,
    95 % t-interval), or — when no two methods share a memory — each method's runs nearest to the grid's
    memory in log space, with their bytes shown."""
    tiers, exact = _memory_tiers(rs)
    md = []
    for target in tiers:
        kib = target / 1024
        md += ["", f"## {scene}: equal memory ({kib:.1f} KiB of probe data)", ""]
        if not exact:
            md += ["_No two methods hold the same bytes: each method's runs nearest to this memory._", ""]
        md += [
            f"| method | memory KiB | probes | runs | {figure_words('mse')} [95 % t-interval over runs] "
            "| how |",
            "|---|---:|---|---:|---:|---|",
        ]
        for lab in labels:
            mine = [r for r in rs if r["label"] == lab and memory(r) is not None]
            if not mine:
                continue
            near = min({memory(r) for r in mine}, key=lambda b: (abs(math.log(b / target)), b))
            if exact and near != target:
                continue
            at = [r for r in mine if memory(r) == near]
            q = log_t_interval([v for r in at if (v := mse(r)) is not None])
            counts = ", ".join(map(str, sorted({r["n_probes"] for r in at})))
            how = "equal memory" if near == target else f"nearest memory measured ({near / target - 1:+.0%})"
            md.append(
                f"| {_method(lab, at, twins)} | {near / 1024:.1f} | {counts} | {len(at)} | {_ci(q)} | {how} |"
            )
    return md


def _usable(r: dict) -> int:
    """The run's usable probes (its evaluation's ``n_probes_usable``; its probe count for a run without)."""
    ev = evaluation(r)
    n = None if ev is None else ev.settings.n_probes_usable
    return r["n_probes"] if n is None else n


def _paired_table(rs, labels, scene, count: int, twins: dict) -> list[str]:
    """At exactly ``count`` probes (exact budgets): each method ÷ the grid on the same seed, glossy and
    diffuse indirect, with the seed interval (:func:`seed_paired_ratio`) and the usable probes."""
    at = [r for r in rs if r["n_probes"] == count]
    grid = {r["seed"]: r for r in at if r["label"] == comparator()}
    md = [
        "",
        f"## {scene}: exactly {count} probes, each seed against the grid's run on the same seed",
        "",
        "Geometric mean of method ÷ grid over seeds, 95 % t-interval in log space (an interval that "
        "holds 1 cannot tell the method from the grid); usable = probes the bake found in free space; "
        "(= grid): the method placed bit-identical probes (`probes.json`) on every seed.",
        "",
        "| method | seeds | glossy ind. ÷ grid [95 %] | diffuse ind. ÷ grid [95 %] | usable probes |",
        "|---|---:|---|---|---|",
    ]
    for lab in labels:
        runs = [r for r in at if r["label"] == lab and r["seed"] in grid]
        if not runs:
            continue
        ratios = []
        for comp in (PRIMARY, "diffuse_indirect"):
            pairs = [(v, w) for r in runs if (v := mse(r, comp)) and (w := mse(grid[r["seed"]], comp))]
            ratios.append(_ci(seed_paired_ratio(pairs), ".2f"))
        usable = sorted(_usable(r) for r in runs)
        md.append(
            f"| {_method(lab, runs, twins)} | {len(runs)} | {ratios[0]} | {ratios[1]} "
            f"| {', '.join(map(str, usable))} |"
        )
    return md


def _equal_time_table(rs, labels, scene, g_time: float, g_count: int, g_mse: float, twins) -> list[str]:
    """Each method's best cell (its runs at one probe count: geometric-mean MSE over seeds) among the cells
    no slower (median placement + bake run time, no compilation) than the grid's cell at ``g_count``; the
    grid's row is that cell itself, so the grid ÷ grid is 1 by construction."""
    md = [
        "",
        f"## {scene}: equal time (placement + bake run time ≤ {g_time:.1f} s, the grid's time)",
        "",
        "Run time without JIT compilation (`place_bake_run_s`): the compilation a sweep's first run "
        "pays is shared by the runs after it and would otherwise decide this table. A cell is a method's "
        f"runs at one probe count; its time is their median, its {figure_words('mse')} their geometric mean "
        f"[95 % t-interval], as the grid's at {g_count} probes that ÷ grid divides by — so a lucky seed "
        "does not decide the ranking, and the grid's row is its own cell (÷ grid 1.00).",
        "",
        *_unsplit_note(rs),
    ]
    md += [
        f"| method | best {figure_words('mse')} within the time [95 %] | probes | ÷ grid | runs "
        "| median run s |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    by_label = count_cells(rs)
    for lab, by_n in ((lab, by_label.get(lab)) for lab in labels):
        if not by_n:
            continue
        if lab == comparator():
            ok = {g_count: by_n[g_count]}
        else:
            ok = {n: c for n, c in by_n.items() if (t := median_run_s(c)) is not None and t <= g_time}
        if ok:
            qs = {n: log_t_interval([mse(r) for r in c]) for n, c in ok.items()}
            n = min(qs, key=lambda k: (qs[k][0], k))
            md.append(
                f"| {_method(lab, ok[n], twins)} | {_ci(qs[n])} | {n} | {_fmt(qs[n][0] / g_mse, '.2f')} "
                f"| {len(ok[n])} | {_fmt(median_run_s(ok[n]), '.1f')} |"
            )
        else:
            fastest = min((t for c in by_n.values() if (t := median_run_s(c)) is not None), default=math.nan)
            md.append(f"| {lab} | — (fastest cell {fastest:.1f} s) | — | — | — | — |")
    return md


def _equal_quality_table(rs, labels, scene, g_mse: float, twins: dict) -> list[str]:
    """Each method's fewest probes whose cell (geometric-mean MSE over its runs at that count) reaches the
    grid's cell, with that cell's median run time."""
    md = ["", f"## {scene}: equal quality ({figure_words('mse')} ≤ {g_mse:.3g}, the grid's)", ""]
    md += [
        "A method's runs at one probe count reach it when their geometric mean does (not its luckiest seed).",
        "",
        "| method | fewest probes reaching it "
        "| its placement + bake run s (no compilation), median of its runs |",
        "|---|---:|---:|",
    ]
    by_label = count_cells(rs)
    for lab, by_n in ((lab, by_label.get(lab)) for lab in labels):
        if not by_n:
            continue
        ok = sorted(
            n for n, c in by_n.items() if log_t_interval([mse(r) for r in c])[0] <= g_mse * (1 + 1e-9)
        )
        if ok:
            md.append(
                f"| {_method(lab, by_n[ok[0]], twins)} | {ok[0]} | {_fmt(median_run_s(by_n[ok[0]]), '.1f')} |"
            )
        else:
            md.append(f"| {lab} | not reached in these runs | — |")
    return md


def _scene_tables(runs: list[dict], labels: list[str], scene: str, twins: dict) -> list[str]:
    """One scene's equal-count, equal-memory, equal-time and equal-quality tables (all but equal memory
    measured against the grid's cell at its count: the geometric mean of its runs there)."""
    rs = [r for r in runs if r["scene"] == scene and mse(r) is not None]
    grid = [r for r in rs if r["label"] == comparator()]
    memory_md = _equal_memory_table(rs, labels, scene, twins)
    if not rs or not grid:
        return [
            "",
            f"_{scene}: equal-count / time / quality tables need evaluated runs including `grid`._",
            *memory_md,
        ]
    g_count = grid_count(grid)
    g_cell = [r for r in grid if r["n_probes"] == g_count]
    g_time = median_run_s(g_cell)
    g_time = math.nan if g_time is None else g_time
    g_mse = log_t_interval([mse(r) for r in g_cell])[0]
    paired = []
    for count in sorted({r["n_probes"] for r in grid}):  # exact budgets: every method at the grid's count
        if len({r["label"] for r in rs if r["n_probes"] == count}) > 1:
            paired += _paired_table(rs, labels, scene, count, twins)
    return (
        paired
        + _equal_count_table(rs, labels, scene, g_count, g_mse, twins)
        + memory_md
        + _equal_time_table(rs, labels, scene, g_time, g_count, g_mse, twins)
        + _equal_quality_table(rs, labels, scene, g_mse, twins)
    )


def _tables(runs: list[dict], labels: list[str]) -> list[str]:
    """The report's Markdown tables: every run, then per scene the grid-relative comparisons."""
    md = _all_runs_table(runs, labels)
    twins = placement_twins(runs, labels)
    for scene in sorted({r["scene"] for r in runs}):
        md += _scene_tables(runs, labels, scene, twins)
    return md


STABILITY_TEXT = (
    "A run *fails* when its placement does not cover the whole surface (`coverage<100%`: short of 1 by "
    "more than the tolerance of the search's `target_reached`), leaves probes inside geometry, its "
    "refiner did not converge, its evaluated error is not finite, or its glossy or diffuse indirect "
    "error is above a black image's (`…>black`: the probes add more wrong light than they recover). Runs "
    "that stopped with an error or were refused leave no finished folder and are not in these tables. "
    "Unresolved rays (the share of the evaluation's glossy rays the light-field tracer could not resolve; "
    "they read the nearest probe's radiance in the ray direction, docs/evaluate.md) are a measured share, "
    "not a failure: their own column, mean and range over the runs."
)


def _share_range(vs: list[float]) -> str:
    """``mean (min – max)`` of shares as percentages; — when none."""
    if not vs:
        return "—"
    return f"{np.mean(vs):.1%} ({min(vs):.1%} – {max(vs):.1%})"


def _stability(runs: list[dict], labels: list[str]) -> list[str]:
    """Spread of each (scene, method) over its seeds and scene offsets, then split by pose."""
    g = group(runs)
    if all(len(v) < 2 for v in g.values()):
        return []
    md = ["## Stability (spread over seeds and scene offsets)", "", STABILITY_TEXT, ""]
    md += [
        "| scene | method | runs | failure rate | probes mean ± sd | coverage min "
        f"| unresolved rays mean (min – max) | {figure_words('mse')} [95 % t-interval] | failures |",
        "|---|---|---:|---:|---:|---:|---:|---:|---|",
    ]
    for (scene, lab), rs in sorted(g.items(), key=lambda kv: (kv[0][0], labels.index(kv[0][1]))):
        n = np.array([r["n_probes"] for r in rs], float)
        worst = min((r for r in rs if full_coverage(r) is not None), key=lambda r: r["coverage"], default={})
        fails = [f for r in rs for f in run_failures(r)]
        rate = sum(bool(run_failures(r)) for r in rs) / len(rs)
        mse_s = _ci(log_t_interval([v for r in rs if (v := mse(r)) is not None]))
        counts = ", ".join(f"{k} ×{fails.count(k)}" for k in sorted(set(fails))) or "none"
        unres = _share_range([v for r in rs if (v := unresolved(r)) is not None])
        md.append(
            f"| {scene} | {lab} | {len(rs)} | {rate:.0%} | {n.mean():.1f} ± {n.std():.1f} "
            f"| {_coverage(worst)} | {unres} | {mse_s} | {counts} |"
        )
    if len({pose(r) for r in runs}) > 1:
        md += ["", "### By perturbation of the scene against the grid", ""]
        md += [
            "| scene | method | pose | runs | failure rate | coverage mean (min – max) "
            "| probes (min – max) |",
            "|---|---|---|---:|---:|---|---|",
        ]
        for (scene, lab), rs in sorted(g.items(), key=lambda kv: (kv[0][0], labels.index(kv[0][1]))):
            for p_name in POSES:
                ps = [r for r in rs if pose(r) == p_name]
                if not ps:
                    continue
                cov = np.array([r["coverage"] for r in ps if r.get("coverage") is not None])
                n = [r["n_probes"] for r in ps]
                rate = sum(bool(run_failures(r)) for r in ps) / len(ps)
                cov_s = f"{cov.mean():.4f} ({cov.min():.4f} – {cov.max():.4f})" if len(cov) else "—"
                md.append(
                    f"| {scene} | {lab} | {p_name} | {len(ps)} | {rate:.0%} | {cov_s} | {min(n)} – {max(n)} |"
                )
    return md


def _top_views(runs: list[dict], out: Path, scenes: dict) -> tuple[list[Path], list[str]]:
    """``top_views/<run>.png`` per run (the folder keeps its earlier name): its probes (``probes.json``)
    in a top and a side view over its scene (``scenes``: :func:`load_scenes`), so probes stacked in
    height, one dot from above, stand apart from the side. Returns the paths and, for runs whose scene
    could not be loaded, the reasons (one line each, once per reason)."""
    from .._core import load_probe_set

    paths, missing, tris = [], [], {}
    for r in runs:
        scene = scenes[r["run"]]
        if isinstance(scene, str):
            missing += [] if scene in missing else [scene]
            continue
        if id(scene) not in tris:
            tris[id(scene)] = np.asarray(scene.vertices)[np.asarray(scene.faces)]
        probes, _ = load_probe_set(r["dir"] / RunFiles.probes)
        pos = np.asarray(probes.pos_world)[np.asarray(probes.active)]
        fig = fig_probe_views(tris[id(scene)], pos, f"{r['label']}: {len(pos)} probes · seed {r['seed']}")
        paths.append(save_figure(fig, out / "top_views" / f"{r['run']}.png", dpi=80))
    return paths, missing


CHARTS = (  # (file stem, section title)
    ("mse_vs_count", "MSE vs probe count (seeds: geometric mean, 95 % t-interval)"),
    ("mse_vs_time", "MSE vs time (run time without JIT compilation; Pareto front marked)"),
    ("memory_vs_mse", "Memory vs MSE"),
    ("error_images", "Error images (one scale)"),
)


def _report_md(exp: Path, runs: list[dict], out: Path, scenes: dict) -> tuple[list[str], list[str]]:
    """Draw every figure into ``out`` and return the report's Markdown lines: the title and its line, then
    the rest (report.html puts its 3D views and images between the two)."""
    labels = _labels(runs)
    col = colours(labels)
    figs = [
        fig_mse_vs_count(runs, labels, col),
        fig_mse_vs_time(runs, labels, col),
        fig_memory(runs, labels, col),
        fig_errors(runs),
    ]
    head = [
        f"# {exp.name}",
        "",
        f"{len(runs)} finished runs in `{exp}`; every figure below is redrawn from them.",
        "",
    ]
    md = []
    for (stem, title), fig in zip(CHARTS, figs, strict=True):
        if fig is None:
            md += [f"## {title}", "", "_no evaluated runs: nothing to draw_", ""]
            continue
        save_figure(fig, out / f"{stem}.png", dpi=100 if stem == "error_images" else 110)
        md += [f"## {title}", "", f"![{title}]({stem}.png)", ""]
    views, missing = _top_views(runs, out, scenes)
    md += ["## Probe layouts (top and side views)", ""]
    md += [f"_{why}_" for why in missing] + ([""] if missing else [])
    md += [" ".join(f"![{p.stem}](top_views/{p.name})" for p in views), ""]
    md += _tables(runs, labels)
    md += ["", *_stability(runs, labels)]
    if (stab := fig_stability(runs, labels, col)) is not None:
        save_figure(stab, out / "stability.png")
        md += ["", "![Uncovered surface per run](stability.png)", ""]
    return head, md


def make_report(exp_dir: str | os.PathLike) -> Path:
    """Write ``<exp_dir>/report/`` (report.md, its PNG charts and report.html, the same report in one
    self-contained page with images and 3D views: ``_report_html``) from the finished runs; returns
    report.md.

    Raises:
        ProbeplaceError: no finished run under ``exp_dir``.
    """
    from .._core import ProbeplaceError

    exp = Path(exp_dir)
    runs = load_runs(exp)
    if not runs:
        raise ProbeplaceError(f"{exp}: no finished run (folders with a DONE marker) to report on")
    final = exp / "report"
    partial = exp / f".report.partial-{os.getpid()}"
    shutil.rmtree(partial, ignore_errors=True)
    partial.mkdir(parents=True)
    try:
        scenes = load_scenes(runs)
        head, body = _report_md(exp, runs, partial, scenes)
        (partial / "report.md").write_text("\n".join(head + body) + "\n")
        write_report_html(partial, runs, _labels(runs), head, body, scenes)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    if final.exists():
        shutil.rmtree(final)
    os.replace(partial, final)
    return final / "report.md"
