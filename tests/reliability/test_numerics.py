"""Numerical robustness (issue 9): no NaN in outputs or gradients for grazing rays, probes exactly on
surfaces, zero-area triangles and coincident probes. Every test runs under ``jax.debug_nans(True)``,
which raises as soon as a jitted computation produces a NaN (masked-out NaNs in a ``where`` included
when they reach an output or a gradient).

Oracles: finiteness under debug_nans, plus closed forms where one exists (the distance a grazing ray
travels along the Cornell box's floor to the far wall; the derivative of a hit distance along the ray).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.experimental import checkify

from probeplace.geometry import BruteForceCaster, intersect_triangles, soft_visibility, sphere_trace

from .conftest import cornell_probes


@pytest.fixture(autouse=True)
def _debug_nans():
    with jax.debug_nans(True):
        yield


@pytest.fixture(scope="module")
def problem(cornell):
    """A small placement problem (its SDF is shared by the sphere-tracing and visibility tests)."""
    from probeplace.placement import FitnessConfig, make_problem

    return make_problem(cornell, key=jax.random.key(2), n_samples=128, config=FitnessConfig(n_steps=8))


def _finite(tree, label):
    for leaf in jax.tree_util.tree_leaves(tree):
        a = np.asarray(leaf)
        if a.dtype.kind == "f":
            assert not np.isnan(a).any(), f"{label}: NaN"


def _size(scene):
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    return lo, hi


# ------------------------------------------------------------------------------------------ casters
def test_grazing_rays_on_the_floor_plane(cornell):
    """Rays lying in the floor's plane (y = 0), from points on the floor: no NaN; those that meet a wall
    head-on report the closed-form distance to it (the floor's own triangles are parallel: no hit)."""
    _, hi = _size(cornell)
    n = 32
    x = np.linspace(0.02, 0.12, n) * hi[0]  # clear of the short block (x ≳ 0.15·556)
    o = np.stack([x, np.zeros(n), np.full(n, 0.05 * hi[2])], axis=1)
    d = np.tile([0.0, 0.0, 1.0], (n, 1))  # along +z, inside the floor plane
    hit = BruteForceCaster(cornell).closest_hit(jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32))
    _finite(hit, "grazing")
    t = np.asarray(hit.t, np.float64)
    # rays that meet the back wall (normal −z) travel from z = 0.05·559.2 to it: t = z_wall − z_origin
    facing = np.asarray(hit.geo_normal)[:, 2] < -0.99
    assert facing.any()
    np.testing.assert_allclose(t[facing], hi[2] - o[facing, 2], rtol=1e-5)


def test_intersection_gradients_for_grazing_rays_and_zero_area_triangles():
    """Möller–Trumbore against a zero-area triangle and a ray parallel to a triangle: t = inf, no NaN; the
    gradient of the hit distance is finite, and for the regular triangle equals the closed form
    ∂t/∂o = −n / (n·d) (the distance to a plane)."""
    v0 = jnp.asarray([[0.0, 0.0, 1.0], [0.0, 0.0, 2.0], [-1.0, -1.0, 0.0]], jnp.float64)
    e1 = jnp.asarray([[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [2.0, 0.0, 0.0]], jnp.float64)
    e2 = jnp.asarray([[0.0, 1.0, 0.0], [2.0, 2.0, 0.0], [0.0, 2.0, 0.0]], jnp.float64)  # row 1: zero area

    def t0(o, d):
        t, _, _ = intersect_triangles(o, d, v0, e1, e2)
        return jnp.where(jnp.isfinite(t[0]), t[0], 0.0)

    o = jnp.asarray([0.25, 0.25, 0.0], jnp.float64)
    d = jnp.asarray([0.0, 0.0, 1.0], jnp.float64)
    t, _, _ = intersect_triangles(o, d, v0, e1, e2)
    assert float(t[0]) == 1.0 and np.isinf(float(t[1]))
    g = jax.grad(t0)(o, d)
    np.testing.assert_allclose(np.asarray(g), [0.0, 0.0, -1.0], atol=1e-12)
    # grazing: the ray lies in the plane of triangle 2 (z = 0) and crosses it
    d_graze = jnp.asarray([1.0, 0.0, 0.0], jnp.float64)
    t, _, _ = intersect_triangles(o, d_graze, v0, e1, e2)
    assert np.isinf(np.asarray(t)).all()
    _finite(jax.grad(t0, argnums=(0, 1))(o, d_graze), "grazing grad")


# ------------------------------------------------------------------------------------ SDF functions
def test_sphere_trace_grazing_and_on_surface(problem, cornell):
    """Sphere tracing along the floor from a point on it and from inside the wall's shell: finite t and
    finite ∂t/∂origin."""
    _, hi = _size(cornell)
    grid = problem.grid
    origins = [
        [0.5 * hi[0], 0.0, 0.1 * hi[2]],
        [0.5 * hi[0], 1e-3, 0.1 * hi[2]],
        [0.0, 0.5 * hi[1], 0.5 * hi[2]],
    ]
    d = jnp.asarray([0.0, 0.0, 1.0], jnp.float32)
    t_max = jnp.float32(2.0 * hi[2])

    @jax.jit
    def t_and_grad(o):
        def t_of(p):
            t, ok = sphere_trace(grid, p, d, t_max)
            return jnp.where(ok, t, 0.0)

        return jax.vmap(jax.value_and_grad(t_of))(o)

    t, g = t_and_grad(jnp.asarray(origins, jnp.float32))
    _finite((t, g), "sphere_trace")


def test_soft_visibility_gradients_at_degenerate_segments(problem, cornell):
    """V(a, b) and ∂V/∂(a, b) finite for a == b, both ends on the floor (a segment along the surface) and
    an end exactly on a wall; V is exactly 1 for a segment shorter than its two margins (closed form)."""
    _, hi = _size(cornell)
    grid = problem.grid
    s = 0.5 * float(grid.voxel_size)
    f = lambda a, b: soft_visibility(grid, a, b, sharpness=s, n_steps=8)
    pts = jnp.asarray(
        [
            [[0.3 * hi[0], 0.4 * hi[1], 0.3 * hi[2]], [0.3 * hi[0], 0.4 * hi[1], 0.3 * hi[2]]],  # a == b
            [[0.5 * hi[0], 0.0, 0.05 * hi[2]], [0.5 * hi[0], 0.0, 0.95 * hi[2]]],  # along the floor
            [[0.0, 0.5 * hi[1], 0.5 * hi[2]], [0.5 * hi[0], 0.5 * hi[1], 0.5 * hi[2]]],  # from the wall
        ],
        jnp.float32,
    )
    v, g = jax.jit(jax.vmap(jax.value_and_grad(f, argnums=(0, 1))))(pts[:, 0], pts[:, 1])
    _finite((v, g), "soft_visibility")
    assert ((np.asarray(v) >= 0.0) & (np.asarray(v) <= 1.0)).all()
    assert float(v[0]) == 1.0


# ---------------------------------------------------------------------------------- fitness gradients
@pytest.mark.parametrize(
    "wang", [False, pytest.param(True, marks=pytest.mark.slow)], ids=["coverage", "coverage+wang"]
)  # Wang's fitness adds a ~20 s gradient compile: slow
def test_fitness_gradients_with_coincident_and_on_surface_probes(problem, cornell, wang):
    """Coverage and Wang fitness gradients with two coincident probes, a probe on the floor and a probe
    exactly at a surface sample (zero-length probe→sample vector): all finite."""
    from probeplace.placement import coverage_objective, wang_fitness

    p = cornell_probes(cornell)[:4].copy()
    p[1] = p[0]  # coincident
    p[2] = [0.5 * float(cornell.bounds[1][0]), 0.0, 0.1 * float(cornell.bounds[1][2])]  # on the floor
    p[3] = np.asarray(problem.position[0])  # exactly on a sample
    pos = jnp.asarray(p, jnp.float32)
    for fn in (coverage_objective, wang_fitness)[: 2 if wang else 1]:
        # One jitted program with a NaN check after every primitive (forward and backward pass): what
        # debug_nans checks when the function runs eagerly, without compiling each primitive apart.
        vg = checkify.checkify(
            jax.value_and_grad(lambda q, fn=fn: fn(problem, q)), errors=checkify.nan_checks
        )
        err, (v, g) = jax.jit(vg)(pos)
        err.throw()
        _finite((v, g), fn.__name__)


# ----------------------------------------------------------------------------------------- tracer
def test_tracer_rays_from_probes_on_surfaces_and_grazing(cornell, cornell_baked):
    """Light-field tracing from every probe position exactly (the coincident pair and the probe on the
    floor included) in the 6 axis directions and along the floor: no NaN, and ``t`` is inf exactly for
    misses."""
    from probeplace.probes import trace_light_field

    _, tr = cornell_baked
    pos = cornell_probes(cornell)
    dirs = np.concatenate([np.eye(3), -np.eye(3), [[1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]] / np.sqrt(2.0)])
    o = np.repeat(pos, len(dirs), axis=0)
    d = np.tile(dirs, (len(pos), 1))
    res = trace_light_field(tr, jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32))
    _finite(res, "trace_light_field")
    status, t = np.asarray(res.status), np.asarray(res.t)
    assert np.array_equal(np.isinf(t), status == 0)
