"""Trilinear lookup, sphere tracing and soft visibility: closed forms, exact ray casting, gradients."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

from probeplace.geometry import (
    SDFGrid,
    lookup_sdf,
    sdf_value,
    sdf_value_and_grad,
    soft_visibility,
    sphere_trace,
    trace_sdf_rays,
)
from probeplace.scene import cornell_box
from tests.reference import sdf_scenes as ref
from tests.reference.ray_triangle import closest_hits


def analytic_grid(fn, lo=-1.0, hi=1.0, n=41, dtype=jnp.float64) -> SDFGrid:
    """Lattice of a closed-form field on [lo, hi]³ (no ``trace``: the tracer reads ``values``)."""
    ax = np.linspace(lo, hi, n)
    p = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), axis=-1)
    return SDFGrid(
        values=jnp.asarray(fn(p), dtype),
        origin=jnp.full(3, lo, dtype),
        voxel_size=jnp.asarray((hi - lo) / (n - 1), dtype),
    )


PLANE_N = np.array([0.3, -0.5, 0.81])
PLANE_N = PLANE_N / np.linalg.norm(PLANE_N)
PLANE_C = 0.1


def plane_grid():
    # A linear field: trilinear interpolation reproduces it exactly, so hits are exact.
    return analytic_grid(lambda p: p @ PLANE_N - PLANE_C)


SPHERE_R = 0.6


def sphere_grid():
    return analytic_grid(lambda p: np.linalg.norm(p, axis=-1) - SPHERE_R)


# check_grads evaluates finite differences on NumPy arrays: the lambdas convert them back to JAX arrays
# because the library's jaxtyping annotations (checked in tests) ask for jax.Array.

# ---------------------------------------------------------------- lookup


def test_lookup_exact_on_linear_field_and_grad():
    grid = plane_grid()
    p = jnp.asarray([0.13, -0.27, 0.41])
    v, g = sdf_value_and_grad(grid, p)
    np.testing.assert_allclose(v, np.asarray(p) @ PLANE_N - PLANE_C, rtol=0, atol=1e-12)
    np.testing.assert_allclose(g, PLANE_N, rtol=0, atol=1e-12)


def test_lookup_gradient_fd_float64():
    grid = sphere_grid()
    check_grads(
        lambda p: sdf_value(grid, jnp.asarray(p)),
        (jnp.asarray([0.31, -0.22, 0.43]),),
        order=1,
        modes=("fwd", "rev"),
    )


def test_lookup_outside_box_stays_a_lower_bound():
    grid = sphere_grid()
    rng = np.random.default_rng(0)
    d = rng.normal(size=(200, 3))
    p = d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(1.8, 4.0, (200, 1))  # outside [-1, 1]³
    got = np.asarray(jax.vmap(lambda x: sdf_value(grid, x))(jnp.asarray(p)))
    assert np.all(got <= np.linalg.norm(p, axis=1) - SPHERE_R + 1e-12)
    assert np.all(got > 0)
    g = jax.vmap(jax.grad(lambda x: sdf_value(grid, x)))(jnp.asarray(p))
    assert np.all(np.isfinite(g))


def test_lookup_dtype_in_equals_out():
    grid = ref.box_sdf()  # float32 leaves
    assert sdf_value(grid, jnp.zeros(3, jnp.float32)).dtype == jnp.float32
    assert sdf_value(grid, jnp.zeros(3, jnp.float64)).dtype == jnp.float64
    assert jax.jit(sdf_value)(grid, jnp.zeros(3, jnp.float32)) == sdf_value(grid, jnp.zeros(3, jnp.float32))


@pytest.mark.isa
@pytest.mark.parametrize("n", [0, 1, 7, 8, 9, 30])
def test_host_lookup_equals_per_point_lookup(n):
    grid = analytic_grid(lambda p: np.linalg.norm(p, axis=-1) - SPHERE_R, dtype=jnp.float32)
    pos = np.random.default_rng(n).uniform(-1.5, 1.5, (n, 3))  # float64 in, some outside the box
    got = lookup_sdf(grid, pos)
    assert got.dtype == np.float32 and got.shape == (n,)
    want = [float(sdf_value(grid, jnp.asarray(p, jnp.float32))) for p in pos]
    # jit + vmap may fuse the trilinear sums differently: a few float32 ulps of the values (≤ ~2.5)
    np.testing.assert_allclose(got, np.asarray(want, np.float32), rtol=0, atol=8 * np.finfo(np.float32).eps)
    assert lookup_sdf(grid, pos.reshape(-1)).shape == (n,)  # any shape that reshapes to (n, 3)


# ---------------------------------------------------------------- sphere tracing


def test_trace_plane_exact_and_gradient_closed_form():
    grid = plane_grid()
    o = jnp.asarray([0.2, 0.4, -0.5])
    d = jnp.asarray([-0.1, -0.3, 0.9]) / np.linalg.norm([-0.1, -0.3, 0.9])
    t, hit = sphere_trace(grid, o, d, 10.0)
    nd = float(PLANE_N @ np.asarray(d))
    assert bool(hit)
    np.testing.assert_allclose(t, (PLANE_C - PLANE_N @ np.asarray(o)) / nd, rtol=1e-10)
    # d t / d origin = −n / (n·d) (implicit function theorem on n·(o + t d) = c).
    g = jax.grad(lambda x: sphere_trace(grid, x, d, 10.0)[0])(o)
    np.testing.assert_allclose(g, -PLANE_N / nd, rtol=1e-8)
    check_grads(lambda x: sphere_trace(grid, jnp.asarray(x), d, 10.0)[0], (o,), order=1, modes=("fwd", "rev"))


def test_trace_sphere_matches_closed_form():
    grid = sphere_grid()
    h = float(grid.voxel_size)
    rng = np.random.default_rng(1)
    o = np.array([-0.95, 0.05, 0.02]) + rng.normal(scale=0.02, size=(64, 3))
    aim = rng.normal(scale=0.15, size=(64, 3))
    d = aim - o
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    b = np.einsum("ij,ij->i", o, d)
    t_exact = -b - np.sqrt(b * b - np.sum(o * o, axis=1) + SPHERE_R**2)
    t, hit = jax.vmap(lambda x, y: sphere_trace(grid, x, y, 10.0))(jnp.asarray(o), jnp.asarray(d))
    assert np.all(np.asarray(hit))
    # Trilinear error of |p| − r is ≤ 3h²/(8r) near the surface (Hessian norm 1/r, (h²/8)·f'' per axis);
    # divided by the incidence cosine (≥ 0.5 for these rays), plus the 0.01·h hit threshold.
    cos = -(np.einsum("ij,ij->i", o + t_exact[:, None] * d, d)) / SPHERE_R
    assert cos.min() > 0.5
    np.testing.assert_allclose(t, t_exact, rtol=0, atol=(3 * h * h / (8 * SPHERE_R) + 0.01 * h) / cos.min())


def test_trace_sphere_gradient_close_to_closed_form():
    grid = sphere_grid()
    h = float(grid.voxel_size)
    o = jnp.asarray([-0.9, 0.1, 0.05])
    d = jnp.asarray([1.0, 0.0, 0.0])
    g = jax.grad(lambda x: sphere_trace(grid, x, d, 10.0)[0])(o)
    p = np.asarray(o) + float(sphere_trace(grid, o, d, 10.0)[0]) * np.asarray(d)
    n = p / np.linalg.norm(p)
    # The interpolated gradient is first-order accurate (error ≲ h·|Hessian| = h/r per component).
    np.testing.assert_allclose(g, -n / (n @ np.asarray(d)), rtol=0, atol=4 * h / SPHERE_R)
    # (No finite-difference check here: the march stops within 0.01·h of the zero, so t(o) is a staircase
    # at FD scales on a curved field; the plane test above checks the implicit gradient against FD.)


def test_trace_degenerate_inputs_are_finite():
    grid = sphere_grid()
    f = lambda o, d: sphere_trace(grid, o, d, 10.0)[0]
    # zero direction: never hits, zero gradient
    t, hit = sphere_trace(grid, jnp.asarray([-0.9, 0.0, 0.0]), jnp.zeros(3), 10.0)
    assert not bool(hit) and np.isinf(t)
    assert np.all(np.isfinite(jax.grad(f, argnums=(0, 1))(jnp.asarray([-0.9, 0.0, 0.0]), jnp.zeros(3))))
    # origin on the surface, ray tangent to it, ray pointing away
    for o, d in [
        ((-SPHERE_R, 0, 0), (1.0, 0, 0)),
        ((-SPHERE_R, 0, 0), (0, 1.0, 0)),
        ((-0.9, 0, 0), (-1.0, 0, 0)),
    ]:
        gr = jax.grad(f, argnums=(0, 1))(jnp.asarray(o), jnp.asarray(d))
        assert all(np.all(np.isfinite(x)) for x in gr)


@pytest.mark.isa
def test_batch_equals_single_ray_and_float32():
    grid = ref.cornell_sdf()
    rng = np.random.default_rng(2)
    o = jnp.asarray(rng.uniform([50, 50, 50], [500, 500, 500], (300, 3)), jnp.float32)
    d = jnp.asarray(rng.normal(size=(300, 3)), jnp.float32)
    t, hit = trace_sdf_rays(grid, o, d, 1e4, lanes=64, steps_per_refill=3)
    assert t.dtype == jnp.float32 and hit.dtype == jnp.bool_
    t1, hit1 = jax.vmap(lambda x, y: sphere_trace(grid, x, y, 1e4))(o, d)
    np.testing.assert_array_equal(hit, hit1)
    # Same march in two programs, which XLA:CPU compiles differently per instruction set (FMA
    # contraction, vector width), so t may differ by rounding — never by a step. The hit is fixed by
    # the zero of the trilinear field (the secant / Newton steps cancel earlier rounding), so the
    # difference is (a) a few ulps of t from forming o + t·d and the last step, and (b) the rounding of
    # the field near its zero — ~16 operations on corner values of at most a cell diagonal — divided by
    # the slope of the field along the ray, which a hit step requires to be at least _MIN_FACING
    # (0.15). 16 ulps for each: measured 8 ulps of t (6e-5 at t = 117) on AVX-512, and a different march
    # (one Newton step more or less) moves t by up to the hit threshold, 0.01 voxel ≈ 0.04 here, well
    # above this bound (≈ 2e-4).
    eps32 = float(np.finfo(np.float32).eps)
    diag = float(grid.voxel_size) * np.sqrt(3.0)
    np.testing.assert_allclose(t, t1, rtol=16 * eps32, atol=16 * eps32 * diag / 0.15)


def test_cornell_hits_agree_with_exact_ray_casting():
    """≥ 98% of sphere-traced hits within one voxel of the exact hit (measured 99.4% on 20k rays; the rest
    are rays grazing the walls' open edges, which the lattice cannot tell from a near miss)."""
    scene, grid = cornell_box(), ref.cornell_sdf()
    h = float(grid.voxel_size)
    rng = np.random.default_rng(3)
    o = rng.uniform([20, 20, 20], [536, 529, 539], (6000, 3))
    v = np.asarray(jax.vmap(lambda x: sdf_value(grid, x))(jnp.asarray(o, jnp.float32)))
    o = o[v > h][:2000]
    d = rng.normal(size=o.shape)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t_ref, _ = closest_hits(o, d, np.asarray(scene.triangles))
    t, hit = trace_sdf_rays(grid, jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32), 1e4)
    t, hit = np.asarray(t, np.float64), np.asarray(hit)
    close = np.abs(np.where(hit, t, 0.0) - np.where(hit, t_ref, 0.0)) <= h
    assert hit.mean() > 0.8  # the open front lets some rays out
    assert close[hit].mean() >= 0.98
    assert np.mean(hit == np.isfinite(t_ref)) >= 0.98


def test_no_retrace_on_new_values():
    grid = ref.cornell_sdf()
    f = eqx.debug.assert_max_traces(lambda o, d: trace_sdf_rays(grid, o, d, 1e4), max_traces=1)
    f = jax.jit(f)
    o = jnp.full((8, 3), 278.0, jnp.float32)
    d = jnp.tile(jnp.asarray([0.0, -1.0, 0.0], jnp.float32), (8, 1))
    f(o, d)
    f(o + 1.0, d)


# ---------------------------------------------------------------- soft visibility


def test_visibility_clear_and_blocked():
    grid = ref.cornell_sdf()
    vis = lambda a, b: float(
        soft_visibility(
            grid, jnp.asarray(a, jnp.float32), jnp.asarray(b, jnp.float32), sharpness=1.0, n_steps=64
        )
    )
    assert vis((278, 420, 280), (278, 420, 60)) > 0.99  # through the empty room
    assert vis((100, 0, 400), (100, 548.8, 400)) > 0.99  # floor to ceiling: endpoints on surfaces
    assert vis((278, 420, 280), (185, 80, 170)) < 0.01  # into the short block
    assert vis((278, 274, 280), (278, 274, 700)) < 0.01  # through the back wall (a one-sided sheet)
    assert vis((130, 100, 40), (470, 100, 40)) > 0.99  # in front of both blocks
    assert vis((60, 100, 200), (500, 100, 200)) < 0.01  # through the short block


def test_visibility_degenerate_and_gradients():
    grid = eqx.tree_at(
        lambda g: (g.values, g.origin, g.voxel_size),
        ref.cornell_sdf(),
        replace_fn=lambda x: x.astype(jnp.float64),
    )
    v = lambda a, b: soft_visibility(grid, a, b, sharpness=2.0, n_steps=32)
    a = jnp.asarray([278.0, 300.0, 280.0])
    assert float(v(a, a)) == 1.0
    ga, gb = jax.grad(v, argnums=(0, 1))(a, a)
    assert np.all(np.isfinite(ga)) and np.all(np.isfinite(gb))
    # On the floor (a surface point) and grazing along it: finite.
    p, q = jnp.asarray([150.0, 0.0, 400.0]), jnp.asarray([400.0, 0.0, 500.0])
    assert all(np.all(np.isfinite(x)) for x in jax.grad(v, argnums=(0, 1))(p, q))
    # A segment partly hidden by the tall block's corner: smooth, gradient matches finite differences.
    a, b = jnp.asarray([150.0, 250.0, 380.0]), jnp.asarray([520.0, 300.0, 330.0])
    val = float(v(a, b))
    assert 0.0 <= val <= 1.0
    check_grads(
        lambda x, y: v(jnp.asarray(x), jnp.asarray(y)), (a, b), order=1, modes=("fwd", "rev"), eps=1e-3
    )


def test_visibility_validates_steps():
    with pytest.raises(ValueError, match="n_steps"):
        soft_visibility(ref.box_sdf(), jnp.zeros(3), jnp.ones(3), sharpness=0.1, n_steps=1)
