"""The report's statistics, figures and equal-memory tables against hand-computed oracles, from synthetic
run folders (``test_report._fake_run``: MSE = scale × A[label] / n, memory = bytes per probe × n).

Figures are inspected as matplotlib objects (scales, legends, titles, labels, the error bars' data), not
as pixels."""

from __future__ import annotations

import math

import numpy as np
import pytest

from probeplace.experiment import load_runs, make_report
from probeplace.experiment._report_charts import (
    DODGE_STEP,
    colours,
    fig_memory,
    fig_mse_vs_count,
    fig_mse_vs_time,
    fig_probe_views,
    fig_stability,
)
from probeplace.experiment._report_data import METRIC_WORDS, log_t_interval, t_interval

from .test_report import A, _fake_run

T975_2 = 4.302652729749464  # Student t, 97.5 % quantile, 2 degrees of freedom (printed tables: 4.303)
SCALES = (1.0, 2.0, 4.0)  # three seeds' MSE multipliers: logs 0, ln 2, 2 ln 2
COUNTS = (4, 16, 64, 271)  # the spread of counts the issue saw


def test_t_interval_matches_the_hand_computed_interval():
    x = [1.0, 2.0, 6.0]
    mean, sd = 3.0, math.sqrt(((1 - 3) ** 2 + (2 - 3) ** 2 + (6 - 3) ** 2) / 2)  # ddof = 1: √7
    half = T975_2 * sd / math.sqrt(3)
    assert t_interval(x) == pytest.approx((mean, mean - half, mean + half), rel=1e-9)
    one = t_interval([5.0])
    assert one[0] == 5.0 and math.isnan(one[1]) and math.isnan(one[2])
    with pytest.raises(ValueError):
        t_interval([])
    # log space: logs 0, ln 2, 2 ln 2 → geometric mean 2, interval 2 · exp(± t · ln 2 / √3)
    g, lo, hi = log_t_interval([1.0, 2.0, 4.0])
    h = T975_2 * math.log(2.0) / math.sqrt(3)
    assert (g, lo, hi) == pytest.approx((2.0, 2.0 * math.exp(-h), 2.0 * math.exp(h)), rel=1e-9)
    assert log_t_interval([0.0, -1.0]) is None


@pytest.fixture(scope="module")
def seeded(tmp_path_factory):
    """grid and skeleton at 4 … 271 probes, three seeds each (MSE × 1, 2, 4)."""
    exp = tmp_path_factory.mktemp("fig") / "seeded"
    for label in ("grid", "skeleton"):
        for n in COUNTS:
            for seed, k in enumerate(SCALES):
                _fake_run(exp, label, n, seed=seed, scale=k, leak=(12, 1000))
    runs = load_runs(exp)
    labels = ["grid", "skeleton"]
    return exp, runs, labels, colours(labels)


def _assert_worded(fig):
    """Every axes has a title, worded x / y labels (no metric key) and a legend; the figure a title."""
    assert fig.get_suptitle()
    for ax in fig.axes:
        if ax.get_label() == "<colorbar>":
            continue
        assert ax.get_title(), ax
        for text in (ax.get_xlabel(), ax.get_ylabel()):
            assert text and "_" not in text, text
        assert ax.get_legend() is not None, ax.get_title()
        assert all(t.get_text() for t in ax.get_legend().get_texts())


def test_mse_vs_count_draws_seed_intervals_on_log_axes(seeded):
    _, runs, labels, col = seeded
    fig = fig_mse_vs_count(runs, labels, col)
    try:
        _assert_worded(fig)
        axes = fig.axes
        assert len(axes) == 3  # glossy, diffuse, full
        assert [ax.get_ylabel() for ax in axes] == [
            METRIC_WORDS[k] for k in ("mse_glossy_indirect", "mse_diffuse_indirect", "mse_full")
        ]
        assert all(ax.get_xscale() == "log" and ax.get_yscale() == "log" for ax in axes)
        ax = axes[0]
        legend = [t.get_text() for t in ax.get_legend().get_texts()]
        floor = METRIC_WORDS["noise_floor_glossy_indirect"]
        assert sorted(legend) == sorted(["grid", "skeleton", "black image (no indirect light)", floor])
        (bars,) = [c for c in ax.containers if c.get_label() == "skeleton"]
        line, _, (segments,) = bars.lines
        x, y = line.get_data()
        h = T975_2 * math.log(2.0) / math.sqrt(3)  # the seeds' log sd is ln 2
        gm = [2.0 * A["skeleton"] / n for n in COUNTS]  # geometric mean of 1, 2, 4 is 2
        # equal counts side by side: skeleton (2nd of 2 series) right of the count, grid left, each half a
        # dodge step of the axis' span (log10 271/4 decades) away, in log space
        shift = 10 ** (0.5 * DODGE_STEP * math.log10(max(COUNTS) / min(COUNTS)))
        np.testing.assert_allclose(x, np.array(COUNTS) * shift, rtol=1e-12)
        (grid_bars,) = [c for c in ax.containers if c.get_label() == "grid"]
        np.testing.assert_allclose(grid_bars.lines[0].get_xdata(), np.array(COUNTS) / shift, rtol=1e-12)
        assert 1.01 < shift < 1.05  # apart by about a marker, still at its count
        assert grid_bars.lines[0].get_marker() != line.get_marker()
        np.testing.assert_allclose(y, gm, rtol=1e-12)
        ends = np.array([seg[:, 1] for seg in segments.get_segments()])  # (lo, hi) per point
        np.testing.assert_allclose(ends[:, 0], np.array(gm) * math.exp(-h), rtol=1e-9)
        np.testing.assert_allclose(ends[:, 1], np.array(gm) * math.exp(h), rtol=1e-9)
    finally:
        import matplotlib.pyplot as plt

        plt.close(fig)


def test_every_figure_has_titles_worded_labels_and_legends(seeded):
    import matplotlib.pyplot as plt

    _, runs, labels, col = seeded
    for build in (fig_mse_vs_time, fig_memory, fig_stability):
        fig = build(runs, labels, col)
        try:
            _assert_worded(fig)
        finally:
            plt.close(fig)
    fig = fig_memory(runs, labels, col)
    assert fig.axes[0].get_xscale() == "log"
    plt.close(fig)


def test_report_tables_carry_the_seed_intervals_and_the_leak(tmp_path):
    """grid at 16 and 64 probes, skeleton at 64, three seeds each (MSE × 1, 2, 4): the equal-count table
    compares at 64 with the seeds' geometric mean and t-interval (a method without a run at 64:
    interpolated, and it says so); the leak column shows pixels and their share."""
    exp = tmp_path / "tables"
    for label, counts in (("grid", (16, 64)), ("skeleton", (64,))):
        for n in counts:
            for seed, k in enumerate(SCALES):
                _fake_run(exp, label, n, seed=seed, scale=k, leak=(12, 1000))
    for n in (16, 271):  # vardis never ran 64 probes: interpolated in log-log (exact for A / n)
        _fake_run(exp, "vardis", n)
    text = make_report(exp).read_text()
    # the grid's counts (three runs each) have median 40; the nearest count it ran, in log space, is 64
    # (|ln 64/40| = 0.47 < |ln 16/40| = 0.92)
    g_count = 64
    eq = text.split("equal probe count")[1].split("\n## ")[0]
    assert eq.startswith(f" ({g_count} probes, the grid's count)")
    h = T975_2 * math.log(2.0) / math.sqrt(3)
    gm = 2.0 * A["skeleton"] / g_count
    want = f"{gm:.3g} [{gm * math.exp(-h):.3g}, {gm * math.exp(h):.3g}]"
    ratio = A["skeleton"] / A["grid"]
    assert f"| skeleton | {want} | {ratio:.2f} | measured at exactly {g_count} (3 runs) |" in eq
    row = next(ln for ln in eq.splitlines() if ln.startswith("| vardis |")).split(" | ")
    assert row[3] == "interpolated (log-log) |"
    v = A["vardis"] / g_count  # ties at the last printed digit (0.03125): compare the numbers
    assert float(row[1]) == pytest.approx(v, rel=2e-3)
    assert float(row[2]) == pytest.approx(v / (2.0 * A["grid"] / g_count), abs=0.006)
    assert "| 12 (1.20%) |" in text  # light leak px (share of judged pixels)


def test_equal_memory_table_groups_runs_with_equal_bytes(tmp_path):
    """grid 8 × 1000 B and skeleton 4 × 2000 B hold 8000 B each: one equal-memory table with both;
    vardis (8 × 1500 B = 12000 B) shares no memory with anyone and is left out of it."""
    exp = tmp_path / "mem"
    for seed in (0, 1):
        _fake_run(exp, "grid", 8, seed=seed, bytes_per_probe=1000)
        _fake_run(exp, "skeleton", 4, seed=seed, bytes_per_probe=2000)
        _fake_run(exp, "vardis", 8, seed=seed, bytes_per_probe=1500)
    text = make_report(exp).read_text()
    tables = text.split("## cornell_box: equal memory")[1:]
    assert len(tables) == 1
    table = tables[0].split("\n## ")[0]
    assert table.startswith(f" ({8000 / 1024:.1f} KiB of probe data)")
    for label, n in (("grid", 8), ("skeleton", 4)):  # two seeds with equal MSEs: a zero-width interval
        v = f"{A[label] / n:.3g}"
        assert f"| {label} | {8000 / 1024:.1f} | {n} | 2 | {v} [{v}, {v}] | equal memory |" in table
    assert "vardis" not in table


def test_equal_memory_falls_back_to_the_nearest_memory_with_bytes_shown(tmp_path):
    """No two methods hold the same bytes: each method's runs nearest to the grid's memory (8000 B)."""
    exp = tmp_path / "near"
    _fake_run(exp, "grid", 8, bytes_per_probe=1000)
    _fake_run(exp, "skeleton", 4, bytes_per_probe=1500)  # 6000 B
    _fake_run(exp, "skeleton", 8, bytes_per_probe=1500)  # 12000 B: farther from 8000 in log space
    text = make_report(exp).read_text()
    table = text.split("## cornell_box: equal memory")[1].split("\n## ")[0]
    assert "No two methods hold the same bytes" in table
    assert f"| grid | {8000 / 1024:.1f} | 8 | 1 | {A['grid'] / 8:.3g} | equal memory |" in table
    assert (
        f"| skeleton | {6000 / 1024:.1f} | 4 | 1 | {A['skeleton'] / 4:.3g} | nearest memory measured (-25%) |"
        in table
    )


def test_probe_views_show_stacked_probes_apart_from_the_side():
    """Two probes at the same (x, z) and different heights: one dot from above, two from the side."""
    import matplotlib.pyplot as plt

    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 0, 1]], [[0, 1, 0], [1, 1, 0], [0, 1, 1]]], float)
    pos = np.array([[0.5, 0.2, 0.5], [0.5, 0.8, 0.5], [0.2, 0.5, 0.3]])
    fig = fig_probe_views(tri, pos, "three probes")
    try:
        top, side = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
        assert top.get_title() == "top view (x–z)" and side.get_title() == "side view (x–y)"
        np.testing.assert_allclose(top.collections[-1].get_offsets(), pos[:, [0, 2]])
        np.testing.assert_allclose(side.collections[-1].get_offsets(), pos[:, [0, 1]])
        assert len({tuple(p) for p in pos[:, [0, 2]]}) == 2 and len({tuple(p) for p in pos[:, [0, 1]]}) == 3
        assert top.yaxis_inverted() and not side.yaxis_inverted()
        assert fig.get_suptitle() == "three probes"
    finally:
        plt.close(fig)
