"""Automatic budget: Cornell box full coverage with ≤ 8 probes; temple vs the smallest full uniform grid."""

import jax
import numpy as np
import pytest

from probeplace.placement import (
    auto_budget,
    binary_coverage,
    binary_visibility,
    make_problem,
    probe_clearance,
    smallest_full_grid,
)


def test_cornell_auto_full_coverage_at_most_8(cornell):
    problem = make_problem(cornell, key=jax.random.key(0))  # default sample density
    res = auto_budget(problem, key=jax.random.key(0))
    assert res.reached
    assert res.coverage == 1.0
    assert 1 <= len(res.pos) <= 8
    # none inside geometry: SDF clearance (and igl's winding numbers per component are what the SDF sign uses)
    assert np.all(probe_clearance(problem, res.pos) >= float(problem.clearance))
    # the reported coverage is what an independent recomputation gives
    assert binary_coverage(problem, binary_visibility(problem, res.pos)) == pytest.approx(res.coverage)
    counts = [k for k, _ in res.curve]
    assert counts[: len(res.pos)] == list(range(1, len(res.pos) + 1))


@pytest.mark.slow
def test_temple_auto_beats_uniform_grid():
    from probeplace.scene import load_scene

    scene = load_scene("temple")
    problem = make_problem(scene, key=jax.random.key(0))
    res = auto_budget(problem, key=jax.random.key(0))
    assert res.reached
    n_grid, cov_grid, _dims = smallest_full_grid(problem, max_probes=2000)
    assert n_grid == -1 or cov_grid >= 1.0 - 1e-9
    assert n_grid == -1 or len(res.pos) < n_grid


def test_auto_budget_reports_the_refiner_status(small):
    """A solver stopped by ``max_steps`` is reported as such (the stability study's "not converged"), and
    ``place`` turns the status into ``refine_converged``."""
    from probeplace.placement._registry import refine_record as _refine_report
    from probeplace.placement.refine._optimistix import OptimistixRefiner

    res = auto_budget(small, key=jax.random.key(0), refiner=OptimistixRefiner(solver="bfgs", max_steps=1))
    assert res.refine_status == "reached max_steps"
    assert isinstance(res.refined, bool)
    assert auto_budget(small, key=jax.random.key(0)).refine_status is None
    assert _refine_report(res.refine_status, res.refined)["refine_converged"] is False
    assert _refine_report("ok", True) == {"refine_status": "ok", "refine_converged": True, "refined": True}
    assert _refine_report(None, False) == {"refined": False}


def test_binding_budget_pools_the_gap_probes(cornell):
    """With a budget that binds before full coverage, gap probes must compete with the seeds: from one
    corner's candidates the seeds-only search fills the budget with corner probes, the pooled search (the
    full search's probes + the seeds) fills it better; the result respects the budget and reports the
    coverage an independent recomputation gives."""
    from probeplace.placement.skeleton._auto import _search

    problem = make_problem(cornell, key=jax.random.key(0))
    lo, hi = np.asarray(problem.lo, np.float64), np.asarray(problem.hi, np.float64)
    frac = np.array([[0.08, 0.08, 0.08], [0.12, 0.08, 0.08], [0.08, 0.12, 0.08]])
    corner = (lo + frac * (hi - lo)).astype(np.float32)  # three candidates huddled in one corner
    seeds_only = _search(problem, key=jax.random.key(0), candidates=corner, max_probes=2)
    res = auto_budget(problem, key=jax.random.key(0), candidates=corner, max_probes=2)
    assert len(seeds_only.pos) == 2 and not seeds_only.reached
    assert 1 <= len(res.pos) <= 2 and res.coverage > seeds_only.coverage + 0.01
    assert binary_coverage(problem, binary_visibility(problem, res.pos)) == pytest.approx(res.coverage)
    assert "pooled_search_s" in res.timings and res.n_candidates > 1
