"""Compiled code is reused: a second call with new values (same shapes) adds no trace.

Each test counts the compiled entries of a module-level jitted function (``_cache_size()``: one entry per
trace) before and after a call with different values; a retrace would add one.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace.placement import FitnessConfig, wang_fitness
from probeplace.placement.baselines import _vardis
from probeplace.placement.refine import _refine
from probeplace.placement.refine._refine import GibbsRefiner
from probeplace.placement.space import _valid

# compile time and compile counts as a fresh process sees them: no persistent compilation cache (issue 32)
pytestmark = pytest.mark.usefixtures("no_persistent_cache")


def _n_traces(fn) -> int:
    """Compiled entries of a ``jax.jit`` or ``eqx.filter_jit`` function."""
    return (fn._cached if isinstance(fn, eqx._jit._JitWrapper) else fn)._cache_size()


def _with_config(problem, **kwargs):
    return eqx.tree_at(lambda q: q.config, problem, FitnessConfig(n_steps=problem.config.n_steps, **kwargs))


def _positions(problem, n=3):
    lo, hi = np.asarray(problem.lo), np.asarray(problem.hi)
    f = np.array([[0.3, 0.5, 0.4], [0.7, 0.4, 0.6], [0.5, 0.6, 0.3]])[:n]
    return jnp.asarray(lo + (hi - lo) * f, jnp.float32)


def test_fitness_config_floats_are_leaves_and_static_options_stay_static(small):
    cfg = small.config
    leaves = jax.tree.leaves(cfg)
    assert len(leaves) == 5 and all(eqx.is_array(x) for x in leaves)  # w1, w2, s, κ, clearance
    assert isinstance(cfg.w1, float) and cfg.w1 == 1.0  # still a plain float on the host (JSON, f-strings)
    other = FitnessConfig(n_steps=cfg.n_steps + 1)
    assert jax.tree.structure(other) != jax.tree.structure(cfg)  # n_steps shapes the code: static


def test_gibbs_sweep_over_weights_compiles_once(small):
    pos = _positions(small, n=2)
    key = jax.random.key(0)
    ra = GibbsRefiner(objective="wang", n_sweeps=1, step=0.05).refine(small, pos, key=key)
    n = _n_traces(_refine._gibbs_run)
    # Doubling both weights doubles every value exactly (acceptance compares ratios), so the run repeats
    # itself at twice the value: the new weights are used, not the ones of the first trace. (``decay``
    # acts after the only sweep.)
    rb = GibbsRefiner(objective="wang", n_sweeps=1, step=0.05, decay=0.5).refine(
        _with_config(small, w1=2.0, w2=2.0), pos, key=key
    )
    assert _n_traces(_refine._gibbs_run) == n
    np.testing.assert_allclose(float(rb.value), 2.0 * float(ra.value), rtol=1e-6)
    np.testing.assert_array_equal(rb.pos, ra.pos)
    pc = _with_config(small, w1=0.5, w2=3.0, sharpness_voxels=0.7, facing_softness=0.2, clearance_voxels=2.5)
    rc = GibbsRefiner(objective="wang", n_sweeps=1, step=0.1, beta=2.0).refine(pc, pos, key=key)
    assert _n_traces(_refine._gibbs_run) == n
    assert rc.pos.dtype == pos.dtype == jnp.float32  # the float64 weights do not promote the run


def test_wang_fitness_under_filter_jit_traces_once_per_shape(small):
    pos = _positions(small, n=2)

    @eqx.filter_jit
    def fitness(problem, p):
        return wang_fitness(problem, p)

    # Eq. 1 is linear in (w1, w2): three weightings, one trace, and the values combine as the weights do
    omega = fitness(_with_config(small, w1=1.0, w2=0.0), pos)
    dist = fitness(_with_config(small, w1=0.0, w2=1.0), pos)
    both = fitness(_with_config(small, w1=2.0, w2=0.5), pos)
    np.testing.assert_allclose(float(both), 2.0 * float(omega) + 0.5 * float(dist), rtol=1e-5)
    fitness(_with_config(small, sharpness_voxels=0.6, facing_softness=0.2, clearance_voxels=3.0), pos)
    assert _n_traces(fitness) == 1
    assert both.dtype == jnp.float32


def test_relocation_compiles_once(small):
    sdf = small.grid
    lo, hi = np.asarray(small.lo, np.float64), np.asarray(small.hi, np.float64)
    rng = np.random.default_rng(0)
    pts = [(lo + (hi - lo) * rng.uniform(0.05, 0.95, (16, 3))).astype(np.float32) for _ in range(2)]
    h = float(sdf.voxel_size)
    _valid.relocate_out(sdf, pts[0], 2.0 * h, 16, lo, hi)
    n = _n_traces(_valid._relocate_points)
    q, ok = _valid.relocate_out(sdf, pts[1], 3.0 * h, 16, lo, hi)
    assert _n_traces(_valid._relocate_points) == n
    assert q.dtype == np.float32 and ok.dtype == bool
    # every relocated point that reports success is clear of the new clearance
    from probeplace.geometry import lookup_sdf

    assert ok.any() and np.all(lookup_sdf(sdf, q[ok]) > 3.0 * h)


def test_vardis_scoring_compiles_once():
    rng = np.random.default_rng(1)
    n_probes, m, j, n_points, c, a = 10, 6, 3, 20, 8, 8

    def args(seed):
        r = np.random.default_rng(seed)
        return (
            jnp.asarray(r.normal(size=(n_probes, m, j)), jnp.float32),
            jnp.asarray(r.normal(size=(n_points, m, j)), jnp.float32),
            jnp.asarray(r.uniform(0.5, 1.0, n_points), jnp.float32),
            jnp.asarray(r.uniform(0.0, 1.0, j), jnp.float32),
            jnp.asarray(r.uniform(0.0, 1.0, n_points), jnp.float32),
            r.integers(0, n_points, (c, a)).astype(np.int32),
            r.integers(0, n_probes, (c, a, 4)).astype(np.int32),
            r.uniform(0.0, 1.0, (c, a, 4)).astype(np.float32),
            rng.uniform(size=(c, a)) < 0.7,
        )

    _vardis._score_chunk(*args(0))
    n = _n_traces(_vardis._score_chunk)
    _vardis._score_chunk(*args(1))
    assert _n_traces(_vardis._score_chunk) == n


@pytest.mark.parametrize("bounce", [0, 1])
def test_evaluation_pixel_uniforms_compile_once_per_bounce(bounce):
    from probeplace.evaluate import _steps

    pix = jnp.arange(64, dtype=jnp.int32)
    smp = jnp.zeros(64, jnp.int32)
    _steps._pixel_uniforms(jnp.uint32(1), pix, smp, bounce)
    n = _n_traces(_steps._pixel_uniforms)
    u = _steps._pixel_uniforms(jnp.uint32(2), pix + 3, smp + 1, bounce)
    assert _n_traces(_steps._pixel_uniforms) == n
    assert u.shape[0] == 64
