"""experiments/ray_allocation.py: the converged MSE from a pixel's first n_i rays against a brute-force mean
over ordered pairs of different rays (and, at n_i = S, against ``evaluate.converged_sq_error``), the
allocation's budget, floor, cap and proportionality, the pilot scores against their definitions, and the
refusals."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from ._util import experiment_script


def _module():
    return experiment_script("ray_allocation")


def _pairs_oracle(x: np.ndarray, n: np.ndarray) -> float:
    """Mean over pixels and channels of the mean over ordered pairs s ≠ t of the first n_i rays of x_s x_t."""
    per_px = [
        np.mean([x[i, s] * x[i, t] for s, t in itertools.permutations(range(n[i]), 2)], axis=0).mean()
        for i in range(x.shape[0])
    ]
    return float(np.mean(per_px))


def _rounding(*arrays) -> float:
    """A bound on float64 rounding in the estimates compared here: they square and sum the same values in
    different orders and cancel m² against Σ x² / n², so each may be off by a few ulps of the largest
    squared value (the estimate itself can be far smaller than its terms: Cauchy rays)."""
    return 1e-12 * max(float(np.max(np.asarray(a, np.float64) ** 2)) for a in arrays)


def test_converged_mse_of_counts_is_the_mean_over_pairs_of_different_rays():
    rng = np.random.default_rng(0)
    x = rng.normal(0.3, 1.0, (5, 7, 3))
    n = np.array([2, 7, 3, 5, 4])
    got = _module().converged_mse_of_counts(x, n)
    assert got == pytest.approx(_pairs_oracle(x, n), rel=0, abs=_rounding(x))


def test_converged_mse_of_every_ray_is_the_evaluations():
    from probeplace.evaluate import converged_sq_error

    rng = np.random.default_rng(1)
    x = rng.standard_cauchy((6, 8, 3))  # heavy tails, as the glossy errors
    e_s = x.reshape(-1, 3) / 8  # evaluate.sample_errors' per-ray parts w (L − L_ref) / S
    expected = converged_sq_error(e_s, e_s.reshape(6, 8, 3).sum(axis=1)).mean()
    got = _module().converged_mse_of_counts(x, np.full(6, 8))
    assert got == pytest.approx(expected, rel=0, abs=_rounding(x))


@pytest.mark.parametrize("n", [np.array([1, 4]), np.array([2, 5]), np.array([3])])
def test_converged_mse_refuses_counts_outside_two_to_s(n):
    with pytest.raises(ValueError, match="one count in"):
        _module().converged_mse_of_counts(np.ones((2, 4, 3)), n)


def test_allocation_spends_the_budget_between_floor_and_cap_in_proportion():
    rng = np.random.default_rng(2)
    score = rng.pareto(1.5, 500)  # a few pixels with most of the score
    n = _module().allocate(score, budget=16, cap=64)
    assert n.sum() == 16 * 500  # whole rays left by rounding down go to the largest remainders
    assert n.min() >= 2 and n.max() <= 64
    assert (n == 64).any()  # the heaviest pixels reach the cap
    interior = (n > 2) & (n < 64)
    # one λ for every pixel between floor and cap: n_i − 1 ≤ λ s_i < n_i + 1
    assert np.max((n[interior] - 1) / score[interior]) < np.min((n[interior] + 1) / score[interior])
    order = np.argsort(score)
    assert np.all(np.diff(n[order]) >= -1)  # a larger score never gets more than one ray fewer


def test_equal_scores_give_every_pixel_the_budget():
    assert np.all(_module().allocate(np.full(10, 0.3), budget=12, cap=64) == 12)


def test_no_score_keeps_every_pixel_at_the_floor():
    assert np.all(_module().allocate(np.zeros(5), budget=8, cap=64) == 2)


def test_a_budget_beyond_the_cap_fills_every_scored_pixel():
    n = _module().allocate(np.array([0.0, 1.0, 5.0]), budget=64, cap=64)
    assert n.tolist() == [2, 64, 64]


@pytest.mark.parametrize("budget", [1, 65])
def test_a_budget_outside_floor_and_cap_is_refused(budget):
    with pytest.raises(ValueError, match="outside"):
        _module().allocate(np.ones(4), budget=budget, cap=64)


def test_pilot_scores():
    x = np.zeros((2, 4, 3))
    x[0] = np.array([1.0, -1.0, 3.0, 1.0])[:, None]  # mean 1, sample σ √(8/3)
    mod = _module()
    sigma = np.sqrt(8 / 3)
    assert mod.pilot_score(x, "black") == pytest.approx([sigma, 0.0])
    assert mod.pilot_score(x, "error") == pytest.approx([sigma * (sigma + 1.0), 0.0])
    with pytest.raises(ValueError, match="unknown score"):
        mod.pilot_score(x, "mean")


@pytest.mark.parametrize(
    "argv",
    [
        ["--seeds", "1"],
        ["--grid", "8x4"],
        ["--bake-spp", "0"],
        ["--glossy-ref-spp", "0"],
        ["--glossy-spp", "4"],
        ["--budgets", "1"],
        ["--glossy-spp", "32", "--budgets", "64"],
    ],
)
def test_bad_arguments_exit_2_before_any_work(argv, capsys):
    with pytest.raises(SystemExit) as e:
        _module().main(argv)
    assert e.value.code == 2
    assert "error:" in capsys.readouterr().err


def test_spreads_of_two_seeds_that_differ_by_a_factor_two():
    """Seed 1's rays are seed 0's doubled: every MSE quadruples and every allocation is the same (scores
    scale, λ absorbs it), so every spread is the population σ over the mean of (m, 4m), 1.5 / 2.5."""
    rng = np.random.default_rng(3)
    x = rng.normal(0.2, 1.0, (40, 16, 3)) * rng.pareto(1.5, (40, 1, 1))
    black = -np.abs(rng.normal(0.5, 1.0, (40, 16, 3)))
    out = _module().spreads([x, 2 * x], [black, 2 * black], budgets=[4, 8])
    assert sorted(out["uniform"]) == [2, 4, 8, 16]
    assert "split" not in out  # no view-dependent parts given
    cvs = [d[k]["cv"] for d in out["uniform"].values() for k in ("plain", "converged")]
    cvs += [d["converged"]["cv"] for rows in out["allocated"].values() for d in rows.values()]
    assert len(cvs) == 12
    assert cvs == pytest.approx([0.6] * 12, rel=1e-9)
    plain = out["uniform"][16]["plain"]["values"]  # each seed's figure, in seed order
    assert plain == pytest.approx(
        [np.mean(x.mean(axis=1) ** 2), np.mean((2 * x).mean(axis=1) ** 2)], rel=1e-12
    )


def test_split_without_view_dependence_is_the_converged_mse():
    """G ≡ 0: D is the ray's error itself and the pool adds nothing, so the split estimate is the U-statistic
    of all S rays."""
    rng = np.random.default_rng(4)
    x = rng.standard_cauchy((9, 6, 3))
    mod = _module()
    got = mod.split_converged(x, np.zeros_like(x), np.zeros((9, 5, 3)))
    assert got == pytest.approx(mod.converged_mse_of_counts(x, np.full(9, 6)), rel=0, abs=_rounding(x))


def test_split_with_a_known_view_dependent_mean():
    """The pool's rays all equal c (no variance), the own rays' G is c too: D − Ḡ is x again and the split
    estimate is once more the U-statistic of x."""
    rng = np.random.default_rng(5)
    x = rng.normal(0.1, 1.0, (7, 4, 3))
    c = rng.normal(0.0, 1.0, (7, 1, 3))
    mod = _module()
    got = mod.split_converged(x, np.broadcast_to(c, x.shape), np.broadcast_to(c, (7, 3, 3)))
    assert got == pytest.approx(mod.converged_mse_of_counts(x, np.full(7, 4)), rel=0, abs=_rounding(x, c))


def test_per_ray_is_each_rays_weighted_difference():
    w = np.array([[1.0, 2.0, 3.0], [0.5, 0.5, 0.5], [0.0, 0.0, 0.0], [2.0, 1.0, 1.0]])
    est, ref = np.full((4, 3), 3.0), np.full((4, 3), 1.0)
    got = _module().per_ray(w, est, ref, spp=2)
    assert got.shape == (2, 2, 3)
    assert got.reshape(4, 3) == pytest.approx(2.0 * w)


def test_split_pools_the_next_seeds_views():
    """Seed j's view-dependent mean comes from seeds j + 1 … j + m (mod N), never its own rays."""
    rng = np.random.default_rng(6)
    xs = [rng.normal(0.3, 1.0, (8, 4, 3)) for _ in range(3)]
    vs = [rng.normal(0.0, 0.5, (8, 4, 3)) for _ in range(3)]
    mod = _module()
    out = mod.spreads(xs, [-np.abs(x) for x in xs], budgets=[2], views=vs)
    assert {m: d["pool_rays"] for m, d in out["split"].items()} == {1: 4, 2: 8}
    one = [mod.split_converged(xs[j], vs[j], vs[(j + 1) % 3]) for j in range(3)]
    two = [
        mod.split_converged(xs[j], vs[j], np.concatenate([vs[(j + 1) % 3], vs[(j + 2) % 3]], 1))
        for j in range(3)
    ]
    tol = _rounding(*xs, *vs)
    assert out["split"][1]["converged"]["mean"] == pytest.approx(np.mean(one), rel=0, abs=tol)
    assert out["split"][2]["converged"]["mean"] == pytest.approx(np.mean(two), rel=0, abs=tol)
