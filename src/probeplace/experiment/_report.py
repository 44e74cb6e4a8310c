"""Charts and a Markdown report redrawn from the saved files of an experiment (``experiments/report.py``).

Reads only finished run folders (``DONE``): ``metrics.json``, ``config.yaml``, ``probes.json`` and
``eval/images.exr``. Writes ``<experiment dir>/report/`` atomically: ``report.md``, ``mse_vs_count.png``,
``mse_vs_time.png`` (placement + bake, and shading per frame, Pareto front marked), ``memory_vs_mse.png``,
``error_images.png`` (one colour scale), ``top_views/<run>.png`` and, with several seeds or scene offsets,
the stability tables.

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
from collections import defaultdict
from pathlib import Path

import numpy as np

from .._core import load_pyplot
from ._results import iter_runs

PRIMARY = "mse_glossy_indirect"
MSE_KEYS = ("mse_glossy_indirect", "mse_diffuse_indirect", "mse_full")


def load_runs(exp_dir: str | os.PathLike) -> list[dict]:
    """One record per finished run: its metrics plus ``dir`` (Path)."""
    runs = []
    for d in iter_runs(exp_dir):
        m = json.loads((d / "metrics.json").read_text())
        m["dir"] = d
        runs.append(m)
    return runs


def _mse(r: dict, key: str = PRIMARY) -> float | None:
    v = (r.get("eval") or {}).get(key)
    return float(v) if isinstance(v, int | float) and math.isfinite(v) else None


def _black_mse(r: dict, key: str = PRIMARY) -> float | None:
    """MSE of a black image (no indirect light) for ``mse_glossy_indirect`` / ``mse_diffuse_indirect``: the
    evaluation's ``mse_black_*``, else the mean square of the saved reference image (older runs)."""
    comp = key.removeprefix("mse_")
    if comp not in ("glossy_indirect", "diffuse_indirect"):
        return None
    v = _mse(r, f"mse_black_{comp}")
    if v is not None:
        return v
    exr = r["dir"] / "eval" / "images.exr"
    if not exr.exists():
        return None
    from ..render._image_io import load_exr

    ref = load_exr(exr).get(f"ref_{comp}")
    return None if ref is None else float(np.mean(np.asarray(ref, np.float64) ** 2))


def _run_s(r: dict) -> float | None:
    """Placement + bake run time without JIT compilation (``timings.place_bake_run_s``); for runs written
    before the compile/run split, their wall time ``place_bake_s`` (compilation included)."""
    t = r.get("timings") or {}
    v = t.get("place_bake_run_s", t.get("place_bake_s"))
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else None


def _stage_run_s(r: dict, stage: str) -> float | None:
    """``<stage>_run_s``, else (older runs) the wall time ``<stage>_s``."""
    t = r.get("timings") or {}
    v = t.get(f"{stage}_run_s", t.get(f"{stage}_s"))
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else None


def _compile_s(r: dict) -> float | None:
    """Placement + bake compile time; ``None`` for runs written before the split."""
    t = r.get("timings") or {}
    if "bake_compile_s" not in t and "place_compile_s" not in t:
        return None
    return float(t.get("place_compile_s", 0.0)) + float(t.get("bake_compile_s", 0.0))


def _n_unsplit(runs: list[dict]) -> int:
    """Runs whose metrics.json predates the compile/run split (times include compilation)."""
    return sum("place_bake_run_s" not in (r.get("timings") or {}) for r in runs)


def _unsplit_note(runs: list[dict]) -> list[str]:
    n = _n_unsplit(runs)
    if not n:
        return []
    return [
        f"_{n} of {len(runs)} runs predate the compile/run split (no `place_bake_run_s` in their "
        "metrics.json): their times are wall times, JIT compilation included._",
        "",
    ]


def _shade_s(r: dict) -> float | None:
    v = (r.get("eval") or {}).get("shading_s_per_frame")
    return float(v) if isinstance(v, int | float) else None


def _memory(r: dict) -> float | None:
    """Bytes of the run's real probes as stored (``metrics.memory``, written by run())."""
    m = r.get("memory") or {}
    return float(m["bytes_total"]) if "bytes_total" in m else None


def pareto_front(points: list) -> list[int]:
    """Indices of the points not dominated in (x, y), both minimised; sorted by x."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def _labels(runs: list[dict]) -> list[str]:
    """Run labels: the reference baselines first (placement registry order), then alphabetical."""
    from ..placement import reference_methods

    first = {m: i for i, m in enumerate(reference_methods())}
    return sorted({r["label"] for r in runs}, key=lambda s: (first.get(s, len(first)), s))


def _colours(labels: list[str]) -> dict:
    import matplotlib

    cmap = matplotlib.colormaps["tab20"]
    return {lab: cmap(i % 20) for i, lab in enumerate(labels)}


def _chart_mse_vs_count(runs, labels, col, out: Path) -> Path | None:
    have = [k for k in MSE_KEYS if any(_mse(r, k) is not None for r in runs)]
    if not have:
        return None
    plt = load_pyplot()
    fig, axes = plt.subplots(1, len(have), figsize=(5 * len(have), 4), constrained_layout=True, squeeze=False)
    for ax, key in zip(axes[0], have, strict=True):
        for lab in labels:
            pts = sorted(
                (r["n_probes"], _mse(r, key)) for r in runs if r["label"] == lab and _mse(r, key) is not None
            )
            if pts:
                x, y = zip(*pts, strict=True)
                ax.plot(x, y, "o-", color=col[lab], label=lab, ms=5)
        floor = [v for r in runs if (v := (r.get("eval") or {}).get(key.replace("mse_", "noise_floor_")))]
        if floor:
            ax.axhline(float(np.median(floor)), ls="--", c="k", lw=0.8, label="reference noise floor")
        black = [v for r in runs if (v := _black_mse(r, key)) is not None]
        if black:
            ax.axhline(float(np.median(black)), ls=":", c="r", lw=1.0, label="black image (no indirect)")
        ax.set_xlabel("probes")
        ax.set_ylabel(key)
        ax.set_yscale("log")
        ax.set_title(key.replace("mse_", "MSE ").replace("_", " "))
    axes[0][0].legend(fontsize=7)
    p = out / "mse_vs_count.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p


def _chart_mse_vs_time(runs, labels, col, out: Path) -> Path | None:
    rs = [r for r in runs if _mse(r) is not None]
    if not rs:
        return None
    plt = load_pyplot()
    old = _n_unsplit(rs)
    name = "placement + bake run time, JIT compilation excluded (s)"
    if old:
        name += f"\n({old} older runs: wall time, compilation included)"
    panels = [(name, _run_s)]
    if any(_shade_s(r) is not None for r in rs):
        panels.append(
            (
                "shading per frame, compilation excluded (ms)",
                lambda r: None if _shade_s(r) is None else 1e3 * _shade_s(r),
            )
        )
    fig, axes = plt.subplots(
        1, len(panels), figsize=(5.5 * len(panels), 4.2), constrained_layout=True, squeeze=False
    )
    for ax, (name, fx) in zip(axes[0], panels, strict=True):
        pts = [(fx(r), _mse(r), r["label"]) for r in rs if fx(r) is not None]
        for lab in labels:
            p = [(x, y) for x, y, lb in pts if lb == lab]
            if p:
                ax.scatter(*zip(*p, strict=True), color=col[lab], label=lab, s=30, zorder=3)
        front = pareto_front([(x, y) for x, y, _ in pts])
        fx_, fy_ = [pts[i][0] for i in front], [pts[i][1] for i in front]
        ax.step(fx_, fy_, where="post", c="k", lw=1.0, zorder=2, label="Pareto front")
        ax.scatter(fx_, fy_, facecolors="none", edgecolors="k", s=110, zorder=4)
        ax.set_xlabel(name)
        ax.set_ylabel(PRIMARY)
        ax.set_yscale("log")
    axes[0][0].legend(fontsize=7)
    p = out / "mse_vs_time.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p


def _chart_memory(runs, labels, col, out: Path) -> Path | None:
    rs = [r for r in runs if _mse(r) is not None and _memory(r) is not None]
    if not rs:
        return None
    plt = load_pyplot()
    fig, ax = plt.subplots(figsize=(5.5, 4.2), constrained_layout=True)
    for lab in labels:
        p = [(_memory(r) / 1024, _mse(r)) for r in rs if r["label"] == lab]
        if p:
            ax.scatter(*zip(*p, strict=True), color=col[lab], label=lab, s=30)
    ax.set_xlabel("probe memory (KiB)")
    ax.set_ylabel(PRIMARY)
    ax.set_yscale("log")
    ax.legend(fontsize=7)
    p = out / "memory_vs_mse.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p


def _chart_errors(runs, out: Path, component: str = "glossy_indirect") -> Path | None:
    from ..render._image_io import load_exr

    imgs = []
    for r in sorted(runs, key=lambda r: (r["label"], r["n_probes"], r["seed"])):
        exr = r["dir"] / "eval" / "images.exr"
        if exr.is_file():
            layers = load_exr(exr)
            if f"error_{component}" in layers:
                title = f"{r['label']} · {r['n_probes']} probes · seed {r['seed']}"
                imgs.append(
                    (title, layers[f"error_{component}"].mean(axis=-1), layers.get(f"ref_{component}"))
                )
    if not imgs:
        return None
    plt = load_pyplot()
    vmax = float(np.percentile(np.concatenate([e.ravel() for _, e, _ in imgs]), 99)) or 1.0
    n = len(imgs)
    cols = min(n, 4)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(
        rows, cols, figsize=(3.2 * cols, 3.2 * rows + 0.3), constrained_layout=True, squeeze=False
    )
    im = None
    for ax, (name, err, _) in zip(axes.ravel(), imgs, strict=False):
        im = ax.imshow(err, cmap="viridis", vmin=0, vmax=vmax)
        ax.set_title(name, fontsize=8)
    for ax in axes.ravel():
        ax.set_axis_off()
    fig.colorbar(
        im, ax=axes.ravel().tolist(), shrink=0.7, label=f"|probe − reference| {component} (mean RGB)"
    )
    p = out / "error_images.png"
    fig.savefig(p, dpi=100)
    plt.close(fig)
    return p


def _top_views(runs, out: Path) -> list[Path]:
    """Redraw each layout over its scene (``placement.save_top_view``) from probes.json + config.yaml."""
    from .._core import load_probe_set
    from ..placement import save_top_view
    from ._run import load_experiment_scene
    from ._schema import load_config_yaml, to_config

    paths, scenes = [], {}
    for r in runs:
        cfg = to_config(load_config_yaml(r["dir"] / "config.yaml"))
        key = (cfg.scene.name, tuple(cfg.scene.translate_frac), cfg.scene.rotate_deg)
        if key not in scenes:
            scenes[key] = load_experiment_scene(cfg.scene)
        probes, _ = load_probe_set(r["dir"] / "probes.json")
        pos = np.asarray(probes.pos_world)[np.asarray(probes.active)]
        paths.append(
            save_top_view(
                scenes[key],
                pos,
                out / "top_views" / f"{r['run']}.png",
                title=f"{r['label']}: {len(pos)} probes",
            )
        )
    return paths


def _fmt(v, spec=".3g") -> str:
    if v is None:
        return "—"
    if isinstance(v, float) and not math.isfinite(v):
        return "—"
    return format(v, spec) if isinstance(v, int | float) and not isinstance(v, bool) else str(v)


def _group(runs: list[dict]) -> dict:
    """(scene, label) → runs."""
    g = defaultdict(list)
    for r in runs:
        g[(r["scene"], r["label"])].append(r)
    return g


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


def _all_runs_table(runs: list[dict], labels: list[str]) -> list[str]:
    """The "All runs" section: one row per run with its times, errors, memory and failures."""
    md = []
    md += ["## All runs", ""]
    md += [
        "Place s and bake s are run times without JIT compilation; compile s is what placement and bake "
        "spent compiling (the first run of a process pays it for every later run of the same shapes); "
        "shading ms/frame excludes its compile run.",
        "",
        *_unsplit_note(runs),
    ]
    md += [
        "| run | probes | coverage | place s | bake s | compile s | MSE glossy ind. | MSE diffuse ind. "
        "| MSE full | noise floor glossy | shading ms/frame | memory KiB | unresolved | failures |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for r in sorted(runs, key=lambda r: (r["scene"], labels.index(r["label"]), r["n_probes"], r["seed"])):
        e = r.get("eval") or {}
        mem = _memory(r)
        md.append(
            f"| {r['run']} | {r['n_probes']} | {_fmt(r.get('coverage'), '.4f')} "
            f"| {_fmt(_stage_run_s(r, 'place'), '.1f')} | {_fmt(_stage_run_s(r, 'bake'), '.1f')} "
            f"| {_fmt(_compile_s(r), '.1f')} | {_fmt(_mse(r))} | {_fmt(_mse(r, 'mse_diffuse_indirect'))} "
            f"| {_fmt(_mse(r, 'mse_full'))} | {_fmt(e.get('noise_floor_glossy_indirect'))} "
            f"| {_fmt(None if _shade_s(r) is None else 1e3 * _shade_s(r), '.2f')} "
            f"| {_fmt(None if mem is None else mem / 1024, '.1f')} "
            f"| {_fmt(e.get('unresolved_share'), '.4f')} "
            f"| {', '.join(r.get('failures', [])) or 'none'} |"
        )
    return md


def _equal_count_table(rs, by, labels, scene, g_count: float, g_mse: float) -> list[str]:
    """Each method's MSE at the grid's probe count (log-log interpolated, else its nearest count)."""
    md = ["", f"## {scene}: equal probe count ({g_count:g} probes, the grid's count)", ""]
    black = [v for r in rs if (v := _black_mse(r)) is not None]
    if black:
        b = float(np.median(black))
        md += [
            f"A black image (no indirect light) scores {b:.3g} here (÷ grid {b / g_mse:.2f}): a method "
            "above it adds more wrong light than it recovers.",
            "",
        ]
    md += ["| method | MSE glossy ind. at that count | ÷ grid | how |", "|---|---:|---:|---|"]
    for lab in labels:
        pts = [(r["n_probes"], _mse(r)) for r in by.get((scene, lab), [])]
        if not pts:
            continue
        v, how = _interp_log(g_count, pts), "interpolated (log-log)"
        if v is None:
            near = min(pts, key=lambda p: abs(math.log(p[0] / g_count)))
            v, how = near[1], f"nearest count measured: {near[0]}"
        md.append(f"| {lab} | {_fmt(v)} | {_fmt(v / g_mse, '.2f')} | {how} |")
    return md


def seed_paired_ratio(pairs: list[tuple[float, float]]) -> tuple[float, float, float] | None:
    """Geometric mean of ``method ÷ grid`` over seeds (each pair: one seed's two MSEs) with a 95 %
    Student-t interval in log space — the seed-to-seed spread of placement, bake and reference noise
    together. ``(ratio, lo, hi)``; the interval is (nan, nan) with one seed (it cannot be estimated)."""
    logs = np.log([m / g for m, g in pairs if m > 0 and g > 0])
    if not len(logs):
        return None
    mean = float(logs.mean())
    if len(logs) < 2:
        return math.exp(mean), math.nan, math.nan
    from scipy import stats

    half = float(stats.t.ppf(0.975, len(logs) - 1) * logs.std(ddof=1) / math.sqrt(len(logs)))
    return math.exp(mean), math.exp(mean - half), math.exp(mean + half)


def _paired_table(rs, labels, scene, count: int) -> list[str]:
    """At exactly ``count`` probes (exact budgets): each method ÷ the grid on the same seed, glossy and
    diffuse indirect, with the seed interval (:func:`seed_paired_ratio`) and the usable probes."""
    at = [r for r in rs if r["n_probes"] == count]
    grid = {r["seed"]: r for r in at if r["label"] == "grid"}
    md = [
        "",
        f"## {scene}: exactly {count} probes, each seed against the grid's run on the same seed",
        "",
        "Geometric mean of method ÷ grid over seeds, 95 % t-interval in log space (an interval that "
        "holds 1 cannot tell the method from the grid); usable = probes the bake found in free space.",
        "",
        "| method | seeds | glossy ind. ÷ grid [95 %] | diffuse ind. ÷ grid [95 %] | usable probes |",
        "|---|---:|---|---|---|",
    ]
    for lab in labels:
        runs = [r for r in at if r["label"] == lab and r["seed"] in grid]
        if not runs:
            continue
        cells = []
        for key in (PRIMARY, "mse_diffuse_indirect"):
            pairs = [(v, w) for r in runs if (v := _mse(r, key)) and (w := _mse(grid[r["seed"]], key))]
            q = seed_paired_ratio(pairs)
            cells.append("—" if q is None else f"{q[0]:.2f} [{q[1]:.2f}, {q[2]:.2f}]")
        usable = sorted((r.get("eval") or {}).get("n_probes_usable", r["n_probes"]) for r in runs)
        md.append(f"| {lab} | {len(runs)} | {cells[0]} | {cells[1]} | {', '.join(map(str, usable))} |")
    return md


def _equal_time_table(rs, by, labels, scene, g_time: float, g_mse: float) -> list[str]:
    """Each method's best MSE among its runs no slower (placement + bake, no compilation) than the grid."""
    md = [
        "",
        f"## {scene}: equal time (placement + bake run time ≤ {g_time:.1f} s, the grid's time)",
        "",
        "Run time without JIT compilation (`place_bake_run_s`): the compilation a sweep's first run "
        "pays is shared by the runs after it and would otherwise decide this table.",
        "",
        *_unsplit_note(rs),
    ]
    md += ["| method | best MSE glossy ind. within the time | probes | ÷ grid |", "|---|---:|---:|---:|"]
    for lab in labels:
        ok = [r for r in by.get((scene, lab), []) if (v := _run_s(r)) is not None and v <= g_time]
        if ok:
            b = min(ok, key=_mse)
            md.append(f"| {lab} | {_fmt(_mse(b))} | {b['n_probes']} | {_fmt(_mse(b) / g_mse, '.2f')} |")
        else:
            times = [v for r in by.get((scene, lab), []) if (v := _run_s(r)) is not None]
            fastest = min(times, default=math.nan)
            md.append(f"| {lab} | — (fastest run {fastest:.1f} s) | — | — |")
    return md


def _equal_quality_table(by, labels, scene, g_mse: float) -> list[str]:
    """Each method's fewest probes reaching the grid's MSE, with that run's time."""
    md = ["", f"## {scene}: equal quality (MSE glossy ind. ≤ {g_mse:.3g}, the grid's)", ""]
    md += [
        "| method | fewest probes reaching it | its placement + bake run s (no compilation) |",
        "|---|---:|---:|",
    ]
    for lab in labels:
        ok = [r for r in by.get((scene, lab), []) if _mse(r) <= g_mse * (1 + 1e-9)]
        if ok:
            b = min(ok, key=lambda r: r["n_probes"])
            md.append(f"| {lab} | {b['n_probes']} | {_fmt(_run_s(b), '.1f')} |")
        else:
            md.append(f"| {lab} | not reached in these runs | — |")
    return md


def _scene_tables(runs: list[dict], labels: list[str], scene: str) -> list[str]:
    """One scene's equal-count, equal-time and equal-quality tables, all measured against the grid's runs."""
    rs = [r for r in runs if r["scene"] == scene and _mse(r) is not None]
    grid = [r for r in rs if r["label"] == "grid"]
    if not rs or not grid:
        return [
            "",
            f"_{scene}: equal-count / time / quality tables need evaluated runs including `grid`._",
        ]
    g_count = float(np.median([r["n_probes"] for r in grid]))
    g_times = [v for r in grid if (v := _run_s(r)) is not None]
    g_time = float(np.median(g_times)) if g_times else math.nan
    g_mse = _interp_log(g_count, [(r["n_probes"], _mse(r)) for r in grid]) or float(
        np.median([_mse(r) for r in grid])
    )
    by = _group(rs)
    paired = []
    for count in sorted({r["n_probes"] for r in grid}):  # exact budgets: every method at the grid's count
        if len({r["label"] for r in rs if r["n_probes"] == count}) > 1:
            paired += _paired_table(rs, labels, scene, count)
    return (
        paired
        + _equal_count_table(rs, by, labels, scene, g_count, g_mse)
        + _equal_time_table(rs, by, labels, scene, g_time, g_mse)
        + _equal_quality_table(by, labels, scene, g_mse)
    )


def _tables(runs: list[dict], labels: list[str]) -> list[str]:
    """The report's Markdown tables: every run, then per scene the grid-relative comparisons."""
    md = _all_runs_table(runs, labels)
    for scene in sorted({r["scene"] for r in runs}):
        md += _scene_tables(runs, labels, scene)
    return md


def _pose(r: dict) -> str:
    """How the run's scene was perturbed against the grid: base, translated, rotated, or both."""
    moved = any(float(x) != 0.0 for x in r.get("translate_frac") or ())
    turned = float(r.get("rotate_deg") or 0.0) != 0.0
    return {(False, False): "base", (True, False): "translated", (False, True): "rotated"}.get(
        (moved, turned), "translated+rotated"
    )


POSES = ("base", "translated", "rotated", "translated+rotated")


def _stability(runs: list[dict], labels: list[str]) -> list[str]:
    g = _group(runs)
    if all(len(v) < 2 for v in g.values()):
        return []
    md = ["## Stability (spread over seeds and scene offsets)", ""]
    md += [
        "| scene | method | runs | failure rate | probes mean ± sd | coverage min "
        "| MSE glossy mean ± sd | failures |",
        "|---|---|---:|---:|---:|---:|---:|---|",
    ]
    for (scene, lab), rs in sorted(g.items(), key=lambda kv: (kv[0][0], labels.index(kv[0][1]))):
        n = np.array([r["n_probes"] for r in rs], float)
        cov = [r["coverage"] for r in rs if r.get("coverage") is not None]
        fails = [f for r in rs for f in r.get("failures", [])]
        rate = sum(bool(r.get("failures")) for r in rs) / len(rs)
        mses = np.array([v for r in rs if (v := _mse(r)) is not None])
        mse_s = f"{mses.mean():.3g} ± {mses.std():.2g}" if len(mses) else "—"
        counts = ", ".join(f"{k} ×{fails.count(k)}" for k in sorted(set(fails))) or "none"
        md.append(
            f"| {scene} | {lab} | {len(rs)} | {rate:.0%} | {n.mean():.1f} ± {n.std():.1f} "
            f"| {_fmt(min(cov) if cov else None, '.4f')} | {mse_s} | {counts} |"
        )
    if len({_pose(r) for r in runs}) > 1:
        md += ["", "### By perturbation of the scene against the grid", ""]
        md += [
            "| scene | method | pose | runs | failure rate | coverage mean (min – max) "
            "| probes (min – max) |",
            "|---|---|---|---:|---:|---|---|",
        ]
        for (scene, lab), rs in sorted(g.items(), key=lambda kv: (kv[0][0], labels.index(kv[0][1]))):
            for pose in POSES:
                ps = [r for r in rs if _pose(r) == pose]
                if not ps:
                    continue
                cov = np.array([r["coverage"] for r in ps if r.get("coverage") is not None])
                n = [r["n_probes"] for r in ps]
                rate = sum(bool(r.get("failures")) for r in ps) / len(ps)
                cov_s = f"{cov.mean():.4f} ({cov.min():.4f} – {cov.max():.4f})" if len(cov) else "—"
                md.append(
                    f"| {scene} | {lab} | {pose} | {len(ps)} | {rate:.0%} | {cov_s} | {min(n)} – {max(n)} |"
                )
    return md


def _chart_stability(runs, labels, col, out: Path) -> Path | None:
    """Uncovered surface share of every run, per scene and method, marker by pose (seeds jittered apart)."""
    rs = [r for r in runs if r.get("coverage") is not None]
    g = _group(rs)
    if all(len(v) < 2 for v in g.values()):
        return None
    plt = load_pyplot()
    scenes = sorted({r["scene"] for r in rs})
    fig, axes = plt.subplots(
        1, len(scenes), figsize=(4.5 * len(scenes), 4), constrained_layout=True, squeeze=False
    )
    marks = dict(zip(POSES, "os^D", strict=True))
    rng = np.random.default_rng(0)
    floor = 1e-4
    for ax, scene in zip(axes[0], scenes, strict=True):
        labs = [lab for lab in labels if (scene, lab) in g]
        for i, lab in enumerate(labs):
            for pose in POSES:
                ps = [r for r in g[(scene, lab)] if _pose(r) == pose]
                if ps:
                    y = [max(1.0 - r["coverage"], floor) for r in ps]
                    x = i + POSES.index(pose) * 0.18 - 0.27 + rng.uniform(-0.05, 0.05, len(y))
                    ax.scatter(x, y, marker=marks[pose], color=col[lab], s=22, edgecolors="k", lw=0.4)
        ax.set_yscale("log")
        ax.axhline(floor, c="g", lw=0.8, ls="--")
        ax.set_xticks(range(len(labs)), labs, rotation=30, ha="right", fontsize=8)
        ax.set_ylabel("uncovered share of the surface")
        ax.text(len(labs) - 0.5, floor * 1.15, "full coverage", ha="right", va="bottom", fontsize=7, c="g")
        ax.set_title(scene)
    handles = [
        plt.Line2D([], [], marker=marks[p], ls="", color="grey", markeredgecolor="k", label=p)
        for p in POSES
        if any(_pose(r) == p for r in rs)
    ]
    axes[0][0].legend(handles=handles, fontsize=7)
    p = out / "stability.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p


def make_report(exp_dir: str | os.PathLike) -> Path:
    """Write ``<exp_dir>/report/`` (report.md + PNG charts) from the finished runs; returns report.md.

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
        labels = _labels(runs)
        col = _colours(labels)
        charts = [
            _chart_mse_vs_count(runs, labels, col, partial),
            _chart_mse_vs_time(runs, labels, col, partial),
            _chart_memory(runs, labels, col, partial),
            _chart_errors(runs, partial),
        ]
        tops = _top_views(runs, partial)
        name = exp.name
        md = [
            f"# {name}",
            "",
            f"{len(runs)} finished runs in `{exp}`; every figure below is redrawn from them.",
            "",
        ]
        titles = [
            "MSE vs probe count",
            "MSE vs time (run time without JIT compilation; Pareto front marked)",
            "Memory vs MSE",
            "Error images (one scale)",
        ]
        for t, c in zip(titles, charts, strict=True):
            md += [f"## {t}", "", f"![{t}]({c.name})" if c else "_no evaluated runs: nothing to draw_", ""]
        md += ["## Probe layouts (top view)", ""]
        md += [" ".join(f"![{p.stem}](top_views/{p.name})" for p in tops), ""]
        md += _tables(runs, labels)
        md += ["", *_stability(runs, labels)]
        if stab := _chart_stability(runs, labels, col, partial):
            md += ["", f"![Uncovered surface per run]({stab.name})", ""]
        (partial / "report.md").write_text("\n".join(md) + "\n")
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    if final.exists():
        shutil.rmtree(final)
    os.replace(partial, final)
    return final / "report.md"
