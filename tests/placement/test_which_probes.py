"""Which probes the common end of placement moved or added, and each probe's part in the coverage.

Oracles: in a constructed case (probes of which some start inside the Cornell box's blocks) the recorded
relocated indices are exactly the final rows that are not input rows and were not filled, the filled ones
are the rows after the kept ones, and the rest are the input rows bit for bit; per-probe seen / unique
counts equal a slow count over the visibility matrix, and unique + multiply-seen + uncovered = the
coverable samples.
"""

from __future__ import annotations

import numpy as np
import pytest

from probeplace.geometry import build_sdf, lookup_sdf
from probeplace.placement import (
    PlaceRequest,
    binary_visibility,
    coverage_context,
    coverage_detail,
    default_clearance,
    place,
)
from probeplace.placement._finish import make_usable


@pytest.fixture(scope="module")
def setup(cornell):
    sdf = build_sdf(cornell, cache_dir=False)
    return sdf, coverage_context(cornell, PlaceRequest(seed=0), sdf)


def _probes(cornell, sdf, n_free: int, n_inside: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``n_free`` points clear of geometry and ``n_inside`` inside the blocks, shuffled; (points, inside)."""
    lo, hi = np.asarray(cornell.bounds, np.float64)
    rng = np.random.default_rng(seed)
    p = (lo + (hi - lo) * rng.uniform(0.05, 0.95, (4000, 3))).astype(np.float32)
    d = np.asarray(lookup_sdf(sdf, p), np.float64)
    c = default_clearance(cornell, sdf)
    free, inside = p[d > 4 * c][:n_free], p[d < -c][:n_inside]
    assert len(free) == n_free and len(inside) == n_inside
    pts = np.concatenate([free, inside])
    order = rng.permutation(len(pts))
    return pts[order], (np.arange(len(pts)) >= n_free)[order]


def _rows_in(final: np.ndarray, given: np.ndarray) -> np.ndarray:
    """Whether each final row is one of the given rows, bit for bit."""
    g = {r.tobytes() for r in given}
    return np.array([r.tobytes() in g for r in final], bool)


@pytest.mark.parametrize("budget", [6, 9, 4])  # as many, filled by 3, trimmed by 2
def test_relocated_and_filled_are_exactly_the_probes_that_moved_or_came(cornell, setup, budget):
    sdf, cov = setup
    pos, inside = _probes(cornell, sdf, n_free=4, n_inside=2)
    out, record = make_usable(cornell, PlaceRequest(budget=budget, seed=0), pos, sdf=sdf, cov=cov)
    assert len(out) == budget
    filled = np.asarray(record["filled_probes"], np.int64)
    relocated = np.asarray(record["relocated_probes"], np.int64)
    n_kept = budget - len(filled)
    np.testing.assert_array_equal(filled, np.arange(n_kept, budget))
    assert record["budget_fit"]["n_filled"] == len(filled)
    unmoved = _rows_in(out, pos)
    want = np.flatnonzero(~unmoved[:n_kept])
    np.testing.assert_array_equal(relocated, want)
    if budget >= len(pos):  # nothing trimmed: the inside probes are the ones that moved, in input order
        np.testing.assert_array_equal(relocated, np.flatnonzero(inside))
    assert record["projected_probes"] == []  # no region: nothing projected
    assert np.all(np.asarray(lookup_sdf(sdf, out[relocated]), np.float64) > 0)


def test_a_method_that_relocates_itself_is_recorded(cornell, setup):
    """The grid's ``inside="relocate"`` moves probes before the common end: passed on, they are named."""
    sdf, cov = setup
    pos, _ = _probes(cornell, sdf, n_free=5, n_inside=0, seed=1)
    mine = np.zeros(len(pos), bool)
    mine[[1, 3]] = True
    _, record = make_usable(cornell, PlaceRequest(budget=5, seed=0), pos, sdf=sdf, cov=cov, relocated=mine)
    assert record["relocated_probes"] == [1, 3]
    with pytest.raises(ValueError, match="relocated must be"):
        make_usable(cornell, PlaceRequest(budget=5), pos, sdf=sdf, cov=cov, relocated=mine[:2])


def test_coverage_detail_counts_match_a_slow_count(cornell, setup):
    sdf, cov = setup
    pos, _ = _probes(cornell, sdf, n_free=5, n_inside=0, seed=2)
    detail = coverage_detail(cov, pos)
    vis = binary_visibility(cov.problem, pos, caster=cov.caster)
    coverable = np.asarray(cov.problem.coverable, bool)
    area = np.asarray(cov.problem.area, np.float64) * coverable
    n_p, n_s = vis.shape
    seen, unique = np.zeros(n_p, int), np.zeros(n_p, int)
    uncovered, multiple = [], 0
    for s in range(n_s):
        if not coverable[s]:
            continue
        who = [p for p in range(n_p) if vis[p, s]]
        for p in who:
            seen[p] += 1
        if len(who) == 1:
            unique[who[0]] += 1
        elif len(who) >= 2:
            multiple += 1
        else:
            uncovered.append(s)
    np.testing.assert_array_equal(detail.seen, seen)
    np.testing.assert_array_equal(detail.unique, unique)
    np.testing.assert_array_equal(detail.uncovered, uncovered)
    assert detail.n_multiple == multiple
    assert detail.unique.sum() + detail.n_multiple + len(detail.uncovered) == detail.n_coverable
    assert detail.n_coverable == coverable.sum() and detail.n_samples == n_s
    assert 0 < len(detail.uncovered) < detail.n_coverable  # five probes: some samples left unseen
    np.testing.assert_array_equal(detail.uncovered_pos, np.asarray(cov.problem.position)[uncovered])
    np.testing.assert_allclose(detail.seen_area, (vis & coverable) @ area / area.sum(), rtol=1e-12)
    assert detail.coverage == cov.coverage(pos)
    assert detail.coverage == pytest.approx(1.0 - area[uncovered].sum() / area.sum(), rel=1e-12)


def test_place_records_which_probes_and_the_coverage_detail(cornell):
    r = place(cornell, method="grid", budget=7, seed=2)
    meta = r.metadata
    assert len(meta["filled_probes"]) == meta["budget_fit"]["n_filled"]
    assert all(0 <= i < 7 for i in meta["relocated_probes"] + meta["filled_probes"])
    d = r.coverage_detail  # measured from the placement's own visibility pass
    assert d is not None
    assert d.coverage == r.coverage and d.seen.shape == (7,)
    assert "coverage_detail" not in meta and "coverage_context" not in meta
