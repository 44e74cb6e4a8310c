"""The report's figures, built from run records (``_report.load_runs``) as matplotlib Figures.

Each ``fig_*`` function returns a Figure (or None when there is nothing to draw) so that tests inspect
the axes themselves; :func:`save_figure` writes and closes one. Every figure has a title, axis labels in
words (``_report_data.METRIC_WORDS``) and a legend in every panel that draws more than one series. A
cell of several runs (seeds, scene offsets) at one probe count or memory is drawn at its geometric mean
with its 95 % Student-t interval in log space as an error bar (``_report_data.cells``); probe counts
and memory run over decades, so those axes are logarithmic. Methods measured at the same count or memory
are drawn side by side — each series nudged along the log axis by a small fixed step (:func:`dodge`) and
with its own marker — so that one never hides another.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .._core import RunFiles, load_pyplot
from ._report_data import (
    COMPONENTS,
    POSES,
    black_mse,
    cells,
    figure_words,
    group,
    memory,
    mse,
    n_unsplit,
    noise_floor,
    pareto_front,
    pose,
    run_s,
    shade_s,
    words,
)

LEGEND = {"fontsize": 7, "framealpha": 0.8}
MARKERS = "osD^vP<X>*"  # one per method (in label order), cycled
#: Horizontal dodge between neighbouring series, as a share of the log axis' span (about 6 px on a
#: 440 px panel: a marker's width, so equal counts sit side by side).
DODGE_STEP = 0.014


def dodge(i: int, k: int, xs) -> float:
    """Factor for the x values of series ``i`` of ``k`` on a log axis over ``xs``: series spread
    symmetrically around the measured value, neighbours :data:`DODGE_STEP` of the axis' span apart
    (the span in decades, at least one decade)."""
    xs = [float(x) for x in xs if x > 0]
    span = max(math.log10(max(xs) / min(xs)), 1.0) if xs else 1.0
    return 10.0 ** ((i - (k - 1) / 2) * DODGE_STEP * span)


def save_figure(fig, path: Path, dpi: int = 110) -> Path:
    """Write ``fig`` to ``path`` (PNG) and close it."""
    plt = load_pyplot()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def colours(labels: list[str]) -> dict:
    """label → a tab20 colour, stable for the report."""
    import matplotlib

    cmap = matplotlib.colormaps["tab20"]
    return {lab: cmap(i % 20) for i, lab in enumerate(labels)}


def _errorbars(ax, cell: list, colour, label: str, factor: float = 1.0, marker: str = "o") -> None:
    """One series of (x, mean, lo, hi, n) cells: points joined by a line, a 95 % bar where n ≥ 2; x
    multiplied by ``factor`` (:func:`dodge`)."""
    x = np.array([c[0] for c in cell], np.float64) * factor
    m = np.array([c[1] for c in cell], np.float64)
    lo = np.array([c[2] for c in cell], np.float64)
    hi = np.array([c[3] for c in cell], np.float64)
    err = np.stack([np.where(np.isfinite(lo), m - lo, 0.0), np.where(np.isfinite(hi), hi - m, 0.0)])
    ax.errorbar(x, m, yerr=err, fmt=f"{marker}-", color=colour, label=label, ms=4.5, capsize=2.5, lw=1.2)


def _dodged_series(ax, series: dict, labels: list[str], col: dict) -> None:
    """Every label's cells as error bars, side by side (:func:`dodge`), one marker per label."""
    drawn = [lab for lab in labels if lab in series]
    xs = [c[0] for cell in series.values() for c in cell]
    for i, lab in enumerate(drawn):
        marker = MARKERS[labels.index(lab) % len(MARKERS)]
        _errorbars(ax, series[lab], col[lab], lab, dodge(i, len(drawn), xs), marker)


def _log_axis(ax, xs) -> None:
    """Log-scale x axis labelled with plain numbers: the measured values themselves when few (the
    default minor labels, 2×10¹ 3×10¹ …, overlap), else powers of two."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    ax.set_xscale("log")
    xs = sorted({float(x) for x in xs if x > 0})
    if 0 < len(xs) <= 8:
        ax.set_xticks(xs)
    else:
        ax.xaxis.set_major_locator(LogLocator(base=2))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:.3g}"))
    ax.xaxis.set_minor_formatter(NullFormatter())


def _seed_note(runs: list[dict]) -> str:
    """How many runs a plotted point summarises, for a figure's title."""
    per = {}
    for r in runs:
        k = (r["scene"], r["label"], r["n_probes"])
        per[k] = per.get(k, 0) + 1
    lo, hi = min(per.values()), max(per.values())
    if hi == 1:
        return "one run per point (no interval)"
    span = f"{lo}–{hi}" if lo != hi else f"{hi}"
    return f"{span} runs per point (seeds / offsets): geometric mean, bars = 95 % t-interval"


def _mse_count_panel(ax, rs: list[dict], labels, col, comp: str, scene: str) -> None:
    """One panel: ``comp``'s MSE against the probe count, one error-bar series per method."""
    series = cells(rs, lambda r: r["n_probes"], lambda r: mse(r, comp))
    _dodged_series(ax, series, labels, col)
    floor = [v for r in rs if (v := noise_floor(r, comp)) is not None]
    if floor:
        ax.axhline(float(np.median(floor)), ls="--", c="k", lw=0.8, label=figure_words("noise_floor", comp))
    black = [v for r in rs if (v := black_mse(r, comp)) is not None]
    if black:
        ax.axhline(float(np.median(black)), ls=":", c="r", lw=1.0, label=figure_words("mse_black", comp))
    _log_axis(ax, [c[0] for cell in series.values() for c in cell])
    ax.set_yscale("log")
    ax.set_xlabel(f"{words('n_probes')} (log scale; methods at one count side by side)")
    ax.set_ylabel(figure_words("mse", comp))
    ax.set_title(f"{scene}: {figure_words('mse', comp)}", fontsize=10)
    ax.legend(**LEGEND)


def fig_mse_vs_count(runs: list[dict], labels: list[str], col: dict):
    """MSE per component (columns) and scene (rows) against the probe count, log-log, seeds as bars."""
    have = [c for c in COMPONENTS if any(mse(r, c) is not None for r in runs)]
    if not have:
        return None
    plt = load_pyplot()
    scenes = sorted({r["scene"] for r in runs})
    fig, axes = plt.subplots(
        len(scenes),
        len(have),
        figsize=(5 * len(have), 4.2 * len(scenes) + 0.4),
        constrained_layout=True,
        squeeze=False,
    )
    for row, scene in zip(axes, scenes, strict=True):
        rs = [r for r in runs if r["scene"] == scene]
        for ax, comp in zip(row, have, strict=True):
            _mse_count_panel(ax, rs, labels, col, comp, scene)
    fig.suptitle(f"Error against the path-traced reference by probe count — {_seed_note(runs)}", fontsize=10)
    return fig


def _time_panels(rs: list[dict]) -> list[tuple[str, object]]:
    old = n_unsplit(rs)
    name = words("place_bake_run_s")
    if old:
        name += f"\n({old} older runs: wall time, compilation included)"
    panels = [(name, run_s)]
    if any(shade_s(r) is not None for r in rs):
        panels.append(
            (words("shading_ms_per_frame"), lambda r: None if shade_s(r) is None else 1e3 * shade_s(r))
        )
    return panels


def fig_mse_vs_time(runs: list[dict], labels: list[str], col: dict):
    """The primary MSE of every run against its run time (and shading time), Pareto front marked."""
    rs = [r for r in runs if mse(r) is not None]
    if not rs:
        return None
    plt = load_pyplot()
    panels = _time_panels(rs)
    fig, axes = plt.subplots(
        1, len(panels), figsize=(5.5 * len(panels), 4.4), constrained_layout=True, squeeze=False
    )
    for ax, (name, fx) in zip(axes[0], panels, strict=True):
        pts = [(fx(r), mse(r), r["label"]) for r in rs if fx(r) is not None]
        for lab in labels:
            p = [(x, y) for x, y, lb in pts if lb == lab]
            if p:
                ax.scatter(*zip(*p, strict=True), color=col[lab], label=lab, s=30, zorder=3)
        front = pareto_front([(x, y) for x, y, _ in pts])
        fx_, fy_ = [pts[i][0] for i in front], [pts[i][1] for i in front]
        ax.step(fx_, fy_, where="post", c="k", lw=1.0, zorder=2, label="Pareto front")
        ax.scatter(fx_, fy_, facecolors="none", edgecolors="k", s=110, zorder=4)
        ax.set_xlabel(name)
        ax.set_ylabel(figure_words("mse"))
        ax.set_yscale("log")
        ax.set_title(f"{figure_words('mse')} against {name.split(',')[0].split(' (')[0]}", fontsize=10)
        ax.legend(**LEGEND)
    fig.suptitle("Error against time, one point per run (JIT compilation excluded)", fontsize=10)
    return fig


def fig_memory(runs: list[dict], labels: list[str], col: dict):
    """The primary MSE against the bytes of probe data (log-log), runs at equal memory as one bar."""
    rs = [r for r in runs if mse(r) is not None and memory(r) is not None]
    if not rs:
        return None
    plt = load_pyplot()
    fig, ax = plt.subplots(figsize=(5.8, 4.4), constrained_layout=True)
    series = cells(rs, lambda r: memory(r) / 1024, mse)
    _dodged_series(ax, series, labels, col)
    _log_axis(ax, [c[0] for cell in series.values() for c in cell])
    ax.set_yscale("log")
    ax.set_xlabel(f"{words('memory_bytes')} (log scale)")
    ax.set_ylabel(figure_words("mse"))
    ax.set_title(f"{figure_words('mse')} against probe memory", fontsize=10)
    ax.legend(**LEGEND)
    fig.suptitle(f"Error against bytes of probe data\n{_seed_note(rs)}", fontsize=9)
    return fig


def fig_errors(runs: list[dict], component: str = "glossy_indirect"):
    """The per-pixel error images of the runs that saved them, on one colour scale."""
    from ..render import load_exr

    imgs = []
    for r in sorted(runs, key=lambda r: (r["label"], r["n_probes"], r["seed"])):
        exr = r["dir"] / RunFiles.eval_dir / RunFiles.images
        if exr.is_file():
            layers = load_exr(exr)
            if f"error_{component}" in layers:
                title = f"{r['label']} · {r['n_probes']} probes · seed {r['seed']}"
                imgs.append((title, layers[f"error_{component}"].mean(axis=-1)))
    if not imgs:
        return None
    plt = load_pyplot()
    vmax = float(np.percentile(np.concatenate([e.ravel() for _, e in imgs]), 99)) or 1.0
    cols = min(len(imgs), 4)
    rows = math.ceil(len(imgs) / cols)
    fig, axes = plt.subplots(
        rows, cols, figsize=(3.2 * cols, 3.2 * rows + 0.5), constrained_layout=True, squeeze=False
    )
    im = None
    for ax, (name, err) in zip(axes.ravel(), imgs, strict=False):
        im = ax.imshow(err, cmap="viridis", vmin=0, vmax=vmax)
        ax.set_title(name, fontsize=8)
    for ax in axes.ravel():
        ax.set_axis_off()
    words_c = component.replace("_", " ")
    fig.colorbar(im, ax=axes.ravel().tolist(), shrink=0.7, label=f"|probe − reference| {words_c} (mean RGB)")
    fig.suptitle(f"Per-pixel {words_c} error, one colour scale", fontsize=10)
    return fig


def fig_stability(runs: list[dict], labels: list[str], col: dict):
    """Uncovered surface share of every run, per scene and method, marker by pose (seeds jittered apart)."""
    rs = [r for r in runs if r.get("coverage") is not None]
    g = group(rs)
    if all(len(v) < 2 for v in g.values()):
        return None
    plt = load_pyplot()
    scenes = sorted({r["scene"] for r in rs})
    fig, axes = plt.subplots(
        1, len(scenes), figsize=(4.5 * len(scenes), 4.2), constrained_layout=True, squeeze=False
    )
    marks = dict(zip(POSES, "os^D", strict=True))
    rng = np.random.default_rng(0)
    floor = 1e-4
    handles = [
        plt.Line2D([], [], marker=marks[p], ls="", color="grey", markeredgecolor="k", label=p)
        for p in POSES
        if any(pose(r) == p for r in rs)
    ]
    for ax, scene in zip(axes[0], scenes, strict=True):
        labs = [lab for lab in labels if (scene, lab) in g]
        for i, lab in enumerate(labs):
            for ps_name in POSES:
                ps = [r for r in g[(scene, lab)] if pose(r) == ps_name]
                if ps:
                    y = [max(1.0 - r["coverage"], floor) for r in ps]
                    x = i + POSES.index(ps_name) * 0.18 - 0.27 + rng.uniform(-0.05, 0.05, len(y))
                    ax.scatter(x, y, marker=marks[ps_name], color=col[lab], s=22, edgecolors="k", lw=0.4)
        ax.set_yscale("log")
        ax.axhline(floor, c="g", lw=0.8, ls="--")
        ax.set_xticks(range(len(labs)), labs, rotation=30, ha="right", fontsize=8)
        ax.set_xlabel("method")
        ax.set_ylabel(words("uncovered"))
        ax.text(len(labs) - 0.5, floor * 1.15, "full coverage", ha="right", va="bottom", fontsize=7, c="g")
        ax.set_title(f"{scene}: {words('uncovered')} per run", fontsize=10)
        ax.legend(handles=handles, title="scene pose", **LEGEND)
    fig.suptitle("Stability over seeds and scene offsets", fontsize=10)
    return fig


def fig_probe_views(tri: np.ndarray, pos: np.ndarray, title: str):
    """Top view (x right, z down, probes coloured by height y) and side view (x right, y up, coloured by
    depth z) of a probe set over the scene's triangles ``tri`` (n, 3, 3): probes stacked in height, one
    dot in the top view, stand apart in the side view."""
    from matplotlib.collections import PolyCollection

    plt = load_pyplot()
    tri = np.asarray(tri, np.float64).reshape(-1, 3, 3)
    p = np.asarray(pos, np.float64).reshape(-1, 3)
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.2))  # fixed margins: constrained layout doubles the time
    fig.subplots_adjust(left=0.06, right=0.98, bottom=0.1, top=0.88, wspace=0.2)
    views = (("top view", 0, 2, 1, "height y"), ("side view", 0, 1, 2, "depth z"))
    for ax, (name, u, v, depth, cname) in zip(axes, views, strict=True):
        order = np.argsort(tri[:, :, depth].mean(axis=1))  # far triangles first
        flat = tri[order][:, :, [u, v]]
        ax.add_collection(
            PolyCollection(
                flat, facecolors=(0.6, 0.6, 0.6, 0.2), edgecolors=(0.3, 0.3, 0.3, 0.3), linewidths=0.3
            )
        )
        if len(p):
            sc = ax.scatter(p[:, u], p[:, v], c=p[:, depth], cmap="autumn", s=26, edgecolors="k", zorder=3)
            fig.colorbar(sc, ax=ax, label=cname, shrink=0.7)
        ax.autoscale()
        ax.set_aspect("equal")
        if name == "top view":
            ax.invert_yaxis()  # z down, as placement.save_top_view draws it
        ax.set_xlabel("x")
        ax.set_ylabel("xyz"[v])
        ax.set_title(f"{name} (x–{'xyz'[v]})", fontsize=10)
    fig.suptitle(title, fontsize=11)
    return fig
