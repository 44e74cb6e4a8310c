"""Fitness: gradients vs finite differences (float64), binary invariants, coverable mask."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace.placement import (
    FitnessConfig,
    binary_coverage,
    binary_visibility,
    coverage_objective,
    wang_fitness,
)


def _fd_check(f, grad_f, x, direction, eps):
    g = grad_f(x)
    analytic = float(jnp.sum(g * direction))
    fd = float((f(x + eps * direction) - f(x - eps * direction)) / (2 * eps))
    return analytic, fd


@pytest.mark.parametrize("objective", ["coverage", "wang"])
def test_gradient_matches_finite_differences_float64(small, objective):
    f = {"coverage": coverage_objective, "wang": wang_fitness}[objective]
    # Eq. 2 with both terms weighted (w2 = 2 makes the distance term about as large as the solid-angle
    # term): d̄ₖ = Σᵢ aᵢ Vᵢₖ |pₖ − xᵢ| / L is smooth in pₖ, so its gradient must match as well.
    prob = (
        small
        if objective == "coverage"
        else eqx.tree_at(lambda q: q.config, small, FitnessConfig(n_steps=12, w1=1.0, w2=2.0))
    )
    fn = jax.jit(lambda p: f(prob, p))
    grad_fn = jax.jit(jax.grad(lambda p: f(prob, p)))
    pos = jnp.asarray([[150.3, 380.7, 120.2], [420.1, 260.9, 180.4]], jnp.float64)
    rng = np.random.default_rng(0)
    for _ in range(3):
        d = jnp.asarray(rng.normal(size=(2, 3)))
        d = d / jnp.linalg.norm(d)
        # Step 1e-3 mm: far below a voxel (4.37 mm), so the trilinear pieces rarely change in between;
        # float64 makes its rounding error ~1e-13 / 1e-3.
        a, b = _fd_check(fn, grad_fn, pos, d, 1e-3)
        assert fn(pos).dtype == jnp.float64
        assert np.isfinite(a)
        assert a == pytest.approx(b, rel=2e-3, abs=1e-7)


def test_float32_in_float32_out(small):
    pos = jnp.asarray([[150.0, 380.0, 120.0]], jnp.float32)
    assert jax.jit(coverage_objective)(small, pos).dtype == jnp.float32
    assert jax.jit(jax.grad(lambda p: wang_fitness(small, p)))(pos).dtype == jnp.float32


def test_binary_coverage_invariants(small):
    pos = np.asarray([[150.0, 380.0, 120.0], [420.0, 260.0, 180.0], [300.0, 450.0, 450.0]], np.float32)
    vis = binary_visibility(small, pos)
    c_all = binary_coverage(small, vis)
    c_perm = binary_coverage(small, binary_visibility(small, pos[::-1]))
    assert c_all == pytest.approx(c_perm, abs=1e-12)
    singles = [binary_coverage(small, vis[k : k + 1]) for k in range(3)]
    assert max(singles) <= c_all <= min(1.0, sum(singles)) + 1e-12  # union bounds
    # the soft union coverage is a probability-like share as well
    s = float(jax.jit(coverage_objective)(small, jnp.asarray(pos)))
    assert 0.0 < s <= 1.0


def test_probe_inside_block_sees_nothing(small):
    inside = np.asarray([[160.0, 80.0, 150.0]], np.float32)  # the short block's interior
    assert not binary_visibility(small, inside).any()


def test_floor_under_block_not_coverable(small, cornell):
    x = np.asarray(small.position)
    cov = np.asarray(small.coverable)
    # floor samples under the short block's footprint (Cornell data: x 82..240, z 65..225 roughly) —
    # take a safely interior square
    under = (x[:, 1] < 1e-3) & (x[:, 0] > 120) & (x[:, 0] < 200) & (x[:, 2] > 100) & (x[:, 2] < 190)
    if under.any():
        assert not cov[under].any()
    assert cov.mean() > 0.8


def test_views_coverage_counts_what_the_view_cameras_see(small, cornell):
    """``FitnessConfig(coverage="views")`` (issue 34): a sample counts only where some view camera's
    position sees it, against a float64 NumPy oracle (every triangle tested along the lifted segment);
    the views' coverable set is inside the reachable one; a scene without views is refused."""
    from probeplace._core import ConfigError
    from probeplace.geometry import SurfaceSamples
    from probeplace.placement import make_problem
    from probeplace.placement.fitness._fitness import seen_from_views
    from probeplace.scene import build_scene
    from tests.geometry.raycast_reference import ray_triangle_t

    zeros = jnp.zeros(len(small.area), jnp.int32)
    smp = SurfaceSamples(small.position, small.normal, small.area, zeros, zeros)
    got = seen_from_views(cornell, smp)
    x, n = np.asarray(small.position, np.float64), np.asarray(small.normal, np.float64)
    tri = np.asarray(cornell.vertices, np.float64)[np.asarray(cornell.faces)]
    lo, hi = (np.asarray(b, np.float64) for b in cornell.bounds)
    want = np.zeros(len(x), bool)
    for view in cornell.views:
        c = np.asarray(view.position, np.float64)
        facing = np.sum(n * (c - x), axis=1) > 0
        start = x + 1e-4 * np.linalg.norm(hi - lo) * n
        v = c - start
        dist = np.linalg.norm(v, axis=1)
        d = v / dist[:, None]
        t = np.stack([ray_triangle_t(np.repeat(tr[None], len(x), 0), start, d) for tr in tri], axis=1)
        want |= facing & ~np.any((t > 0) & (t < dist[:, None]), axis=1)
    # float32 casting against the float64 oracle: only a segment grazing an edge may differ
    assert np.mean(got != want) <= 0.005
    assert 0.2 < want.mean() < 0.9  # the camera sees some walls, not the blocks' far sides nor behind them
    cfg = FitnessConfig(n_steps=12, coverage="views")
    views = make_problem(cornell, key=jax.random.key(1), n_samples=400, config=cfg)
    cov_v, cov_r = np.asarray(views.coverable), np.asarray(small.coverable)
    assert np.all(cov_r[cov_v]) and cov_v.sum() < cov_r.sum()
    arrays = (np.asarray(cornell.vertices), np.asarray(cornell.faces), np.asarray(cornell.tri_material))
    bare = build_scene("no_views", *arrays, cornell.materials)
    with pytest.raises(ConfigError, match="view cameras"):
        seen_from_views(bare, smp)
