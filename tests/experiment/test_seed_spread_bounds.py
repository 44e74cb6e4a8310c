"""The seed spread's bounds in benchmarks/convergence.py (``cv_interval``, ``cv_upper95``), which decide
issue 33's ``sponza_grid_seed_spread`` ≤ 0.05: against their definition, the share of draws whose bound
holds the true σ / mean, on normal values with a known coefficient of variation."""

from __future__ import annotations

import numpy as np
import pytest

from ._util import benchmark_module


def _convergence():
    return benchmark_module("convergence")


@pytest.mark.parametrize("n", [5, 20])
def test_the_bounds_hold_the_true_spread_as_often_as_they_claim(n):
    """4,000 draws of n normal values of σ / mean 5 %: the one-sided bound lies at or above 5 % in about
    95 % of them, the interval holds it in about 95 %. The binomial σ of a share near 0.95 over 4,000 draws
    is 0.0034; the bounds ignore the mean's own error (σ/√n of it, 1–2 % of the mean here), which moves the
    share by well under a point; ± 0.02 holds both."""
    cv = _convergence()
    rng = np.random.default_rng(7)
    true = 0.05
    draws = rng.normal(1.0, true, size=(4000, n))
    upper = np.array([cv.cv_upper95(d) for d in draws])
    lo, hi = np.array([cv.cv_interval(d) for d in draws]).T
    assert np.mean(upper >= true) == pytest.approx(0.95, abs=0.02)
    assert np.mean((lo <= true) & (true <= hi)) == pytest.approx(0.95, abs=0.02)


def test_the_one_sided_bound_lies_inside_the_interval_above_the_estimate():
    """A 95 % one-sided bound is looser than no bound and tighter than the 97.5 % one (the interval's top)."""
    cv = _convergence()
    for d in np.random.default_rng(3).gamma(4.0, 1.0, size=(50, 10)):
        lo, hi = cv.cv_interval(d)
        assert lo < cv.seed_cv(d) < cv.cv_upper95(d) < hi


@pytest.mark.parametrize("values", [[1.0], [], [-1.0, 0.5]])
def test_no_bound_below_two_values_or_for_a_mean_not_positive(values):
    cv = _convergence()
    assert cv.cv_upper95(values) is None
    assert cv.cv_interval(values) is None


def test_the_target_is_undecided_while_the_bound_is_above_it():
    """The spread target ``≤ 0.05`` is met only when the one-sided bound is under it too: the twenty seeds of
    experiments/README.md §2 (8×4×4 glossy MSE, e-5) decide it (bound 4.9 %); their first two (3.8 %, bound
    ~0.9) do not; a spread above the target is not met whatever the bound."""
    cv = _convergence()
    twenty = [1.14, 1.23, 1.26, 1.23, 1.17, 1.24, 1.26, 1.18, 1.18, 1.20]
    twenty += [1.22, 1.18, 1.15, 1.11, 1.26, 1.23, 1.19, 1.25, 1.24, 1.23]

    def verdict(values):
        v = np.array(values)
        result = {
            "sponza_grid_seed_spread": cv.seed_cv(v),
            "sponza_grid_seed_spread_upper95": cv.cv_upper95(v),
        }
        return cv.targets(result)["sponza_grid_seed_spread"]

    decided = verdict(twenty)
    assert decided["met"] is True and decided["upper95"] == pytest.approx(0.049, abs=0.001)
    two = verdict(twenty[:2])
    assert two["value"] < 0.05 and two["met"] is None and "undecided" in two["why"]
    assert verdict([1.0, 1.2, 0.9, 1.1])["met"] is False
