"""Exact budgets (``_budget``, ``_finish``): every method returns exactly N usable probes, by the stated
trim / fill rules; memory budgets become counts."""

from __future__ import annotations

import numpy as np
import pytest

from probeplace._core import ConfigError
from probeplace.geometry import build_sdf, lookup_sdf
from probeplace.placement import method_names, place
from probeplace.placement.space._budget import (
    count_for_memory,
    fill_order,
    fit_to_budget,
    parse_bytes,
    trim_order,
)

# cheap options so that every method runs in seconds on the Cornell box
CHEAP = {"vardis": {"dense_probes": 64, "n_dirs": 16, "spp": 1, "n_eval": 256}}


def test_trim_removes_least_unique_area_first():
    # probe 0 sees samples 0-1, probe 1 sees 1-2, probe 2 sees 2-3, probe 3 sees 0-3 (everything)
    rows = np.array([[1, 1, 0, 0], [0, 1, 1, 0], [0, 0, 1, 1], [1, 1, 1, 1]], bool)
    area = np.array([1.0, 2.0, 3.0, 4.0])
    pos = np.array([[0, 0, 0], [10, 0, 0], [20, 0, 0], [100, 0, 0]], float)
    # unique areas: probes 0-2 see nothing alone (probe 3 sees all) -> tie at 0, broken by nearest
    # neighbour (probes 0-2 are 10 apart, probe 3 far), then the highest index: probe 2 first; then
    # probes 0, 1 tie again (unique 0): probe 1; then probe 0; probe 3 stays (it alone sees everything)
    assert trim_order(rows, area, pos, 3).tolist() == [2, 1, 0]


def test_trim_prefers_the_most_crowded_probe_on_a_tie():
    rows = np.ones((3, 2), bool)  # everyone sees everything: unique area 0 for all
    pos = np.array([[0, 0, 0], [0.1, 0, 0], [5, 0, 0]], float)
    # probes 0 and 1 are 0.1 apart: the higher index of the two goes first, then (a pair left, 4.9
    # apart, tied) the higher index again
    assert trim_order(rows, np.ones(2), pos, 2).tolist() == [1, 2]


def test_fill_takes_the_farthest_point_first():
    pos = np.array([[0.0, 0, 0]])
    pool = np.array([[1.0, 0, 0], [4.0, 0, 0], [2.0, 0, 0], [3.0, 0, 0]])
    # farthest from 0 is 4; then farthest from {0, 4} is 2; then 1 and 3 tie (1 away): lowest index, 1
    assert fill_order(pos, pool, 3).tolist() == [1, 2, 0]


def test_fit_to_budget_counts_and_records():
    pos = np.zeros((3, 3), np.float32) + np.arange(3)[:, None]
    vis = lambda p: np.ones((len(p), 4), bool)
    out = fit_to_budget(pos, 2, visibility=vis, area=np.ones(4), pool_fn=None)
    assert len(out.pos) == 2 and out.n_trimmed == 1 and out.n_filled == 0
    pool = lambda n: np.full((n + 2, 3), 9.0) + np.arange(n + 2)[:, None]
    out = fit_to_budget(pos, 6, visibility=None, area=np.ones(4), pool_fn=pool)
    assert len(out.pos) == 6 and out.n_filled == 3 and out.short == 0
    np.testing.assert_array_equal(out.pos[:3], pos)  # the method's probes come first, unchanged
    out = fit_to_budget(pos, 9, visibility=None, area=np.ones(4), pool_fn=lambda n: np.ones((2, 3)))
    assert out.short == 4 and out.record()["short"] == 4


@pytest.mark.parametrize(
    ("text", "want"), [("4096", 4096), (4096, 4096), ("64MiB", 64 * 2**20), ("1.5 GB", 1_500_000_000)]
)
def test_memory_sizes_parse(text, want):
    assert parse_bytes(text) == want


@pytest.mark.parametrize("bad", ["", "12 parsecs", "-3MB", 0, True, "MiB"])
def test_bad_memory_sizes_name_the_problem(bad):
    with pytest.raises(ConfigError, match="memory budget"):
        parse_bytes(bad)


# Issue 31: decimal and binary units up to peta, any case, an exponent; the expected bytes written out.
SIZES = [
    ("1TB", 10**12), ("1tb", 10**12), ("1 tB", 10**12), ("1.5TB", 1_500_000_000_000),
    ("1TiB", 2**40), ("1tib", 2**40), ("1 TIB", 2**40), ("1PB", 10**15), ("1PiB", 2**50),
    ("2GB", 2 * 10**9), ("2gb", 2 * 10**9), ("2gib", 2**31), ("0.5 GiB", 2**29), (" 8 GiB ", 2**33),
    ("64MB", 64 * 10**6), ("64mb", 64 * 10**6), ("64MiB", 2**26), ("64mib", 2**26),
    ("64kB", 64_000), ("64KB", 64_000), ("64kb", 64_000), ("64KiB", 65_536), ("64kib", 65_536),
    ("4096B", 4096), ("4096 b", 4096), ("1e9", 10**9), ("1e3MB", 10**9), ("2.5e-3GB", 2_500_000),
]  # fmt: skip


@pytest.mark.parametrize(("text", "want"), SIZES, ids=[t for t, _ in SIZES])
def test_memory_size_table(text, want):
    assert parse_bytes(text) == want


@pytest.mark.parametrize(
    ("bad", "why"),
    [
        ("64Mb", "reads as bits"), ("1Gib", "reads as bits"), ("1Tb", "reads as bits"),
        ("1G", "'G' alone is ambiguous"), ("1t", "'t' alone is ambiguous"), ("1 TeB", "such as '64MiB'"),
        ("1..5GB", "such as '64MiB'"), ("1GB2", "such as '64MiB'"), ("0KB", "positive"), ("0.1B", "positive"),
    ],
)  # fmt: skip
def test_memory_sizes_refused_with_the_reason(bad, why):
    with pytest.raises(ConfigError, match="memory budget") as info:
        parse_bytes(bad)
    assert why in str(info.value)


def test_memory_budget_becomes_a_count():
    assert count_for_memory("1MiB", 100_000) == 10
    with pytest.raises(ConfigError, match="smaller than one probe"):
        count_for_memory(1000, 4096)


@pytest.fixture(scope="module")
def cornell_sdf(cornell):
    return build_sdf(cornell)


@pytest.mark.parametrize("method", method_names())
@pytest.mark.parametrize("n", [5, pytest.param(13, marks=pytest.mark.slow)])  # 13: slow, ~6 min in all
def test_every_method_returns_exactly_the_budget(cornell, cornell_sdf, method, n):
    """Budget N gives exactly N probes, all usable: at least the clearance from geometry."""
    res = place(cornell, method=method, budget=n, options=CHEAP.get(method))
    assert res.n_probes == n
    d = lookup_sdf(cornell_sdf, np.asarray(res.probes.pos_world))
    clearance = res.metadata["valid_space"]["clearance"]
    assert np.all(d >= clearance * (1 - 1e-6)), (d.min(), clearance)
    fit = res.metadata["budget_fit"]
    assert fit["n_before"] - fit["n_trimmed"] + fit["n_filled"] == n


def test_methods_measure_coverage_on_the_same_samples(cornell, cornell_sdf):
    """The coverage problem comes from the seed's ``"coverage"`` stream whatever the method: one seed,
    one set of surface samples, so coverages compare like for like; a rerun is identical."""
    from probeplace.placement._finish import coverage_context
    from probeplace.placement._registry import PlaceRequest

    a = coverage_context(cornell, PlaceRequest(seed=4, caster="sdf"), cornell_sdf).problem
    b = coverage_context(cornell, PlaceRequest(seed=4, caster="sdf"), cornell_sdf).problem
    c = coverage_context(cornell, PlaceRequest(seed=5, caster="sdf"), cornell_sdf).problem
    np.testing.assert_array_equal(np.asarray(a.position), np.asarray(b.position))
    assert a.n_samples != c.n_samples or not np.array_equal(np.asarray(a.position), np.asarray(c.position))
    r1 = place(cornell, method="grid", budget=7, seed=2)
    r2 = place(cornell, method="grid", budget=7, seed=2)
    np.testing.assert_array_equal(np.asarray(r1.probes.pos_world), np.asarray(r2.probes.pos_world))
    assert r1.coverage == r2.coverage
