"""Seeds (ball shrinking closed form, skeleton in free space) and refiners improving from a poor start."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace.placement import (
    get_refiner,
    medial_axis_seeds,
    objective_fn,
    probe_clearance,
    shrink_balls,
    skeleton_seeds,
    stochastic_direction,
)


def test_ball_shrinking_between_parallel_planes():
    # Two planes y=0 (normal +y) and y=2: the medial axis is y=1, radius 1 (closed form).
    g = np.linspace(-5, 5, 41)
    xx, zz = np.meshgrid(g, g)
    lower = np.stack([xx.ravel(), np.zeros(xx.size), zz.ravel()], 1)
    upper = lower + np.array([0.0, 2.0, 0.0])
    surface = np.concatenate([lower, upper])
    p = lower[[0, 500, 840]]
    n = np.tile([0.0, 1.0, 0.0], (3, 1))
    r = shrink_balls(p, n, surface, np.full(3, 10.0))
    np.testing.assert_allclose(r, 1.0, rtol=1e-9)  # exact: the opposite point is on the sample grid


def test_linear_inversion_sampling():
    from probeplace.placement.refine._refine import _sample_linear

    xi = jnp.asarray((np.arange(20000) + 0.5) / 20000)
    x = np.asarray(_sample_linear(jnp.zeros(()), jnp.ones(()), xi))
    # density 2x on [0, 1]: CDF x², so x = √ξ exactly
    np.testing.assert_allclose(x, np.sqrt(np.asarray(xi)), rtol=1e-9, atol=1e-12)


def test_stochastic_direction_drifts_toward_higher_values():
    # Values growing with x only: the x-stage alone has mean 1/3; the y/z stages reweight by the sampled
    # values, so the drift is positive (≥ 1/3 - noise) and y, z stay symmetric.
    signs = np.array([[2 * ((s >> a) & 1) - 1 for a in range(3)] for s in range(8)], np.float64)
    vals = jnp.asarray((signs[:, 0] + 1.0) / 2.0)
    keys = jax.random.split(jax.random.key(0), 4000)
    u = np.asarray(jax.vmap(lambda k: stochastic_direction(vals, k))(keys))
    assert np.all(np.abs(u) <= 1.0 + 1e-12)
    # std of x under that density is √(2/9) ≈ 0.47 → standard error 0.0075; 4 sigma
    assert u[:, 0].mean() > 1.0 / 3.0 - 0.03
    assert abs(u[:, 1].mean()) < 0.03 and abs(u[:, 2].mean()) < 0.03


def test_seeds_in_free_space_and_scene_sized(small):
    for seeds in (skeleton_seeds(small), medial_axis_seeds(small)):
        assert 1 <= len(seeds) < 500
        assert np.all(probe_clearance(small, seeds) > 0)
        lo, hi = np.asarray(small.lo), np.asarray(small.hi)
        assert np.all((seeds >= lo) & (seeds <= hi))


POOR = [[40.0, 40.0, 40.0], [60.0, 50.0, 45.0]]  # two probes bunched in a corner


def _improves(small, name, objective, **kw):
    pos = jnp.asarray(POOR, jnp.float32)
    res = get_refiner(name, objective=objective, **kw).refine(small, pos, key=jax.random.key(0))
    f = objective_fn(small, objective)
    assert res.history.shape[0] >= 1
    assert np.all(np.isfinite(np.asarray(res.history)))
    assert int(res.status) in (0, 1)  # cut short (max_steps / n_sweeps below the defaults): OK or MAX_STEPS
    assert np.all(probe_clearance(small, np.asarray(res.pos)) >= float(small.clearance) * 0.99)
    assert float(f(res.pos)) > float(f(pos)) * 1.05
    # value / start_value: the refiner's objective at the returned / start positions (float32 sums)
    np.testing.assert_allclose(float(res.value), float(f(res.pos)), rtol=1e-5)
    np.testing.assert_allclose(float(res.start_value), float(f(pos)), rtol=1e-5)
    assert res.improved() and res.fitness_gain > 1.05


@pytest.mark.parametrize("objective", ["coverage", "wang"])
def test_gibbs_improves(small, objective):
    _improves(small, "gibbs", objective, n_sweeps=4, beta=50.0)


def test_bfgs_improves(small):
    _improves(small, "bfgs", "coverage", max_steps=10)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["ascent", "nonlinear_cg", "adam", "projected_gradient", "lbfgsb"])
def test_other_refiners_improve(small, name):
    kw = {"n_sweeps": 4} if name == "ascent" else {"max_steps": 15}
    _improves(small, name, "coverage", **kw)


def test_bad_refiner_name():
    from probeplace._core import ConfigError

    with pytest.raises(ConfigError, match="unknown refiner"):
        get_refiner("simplex")
