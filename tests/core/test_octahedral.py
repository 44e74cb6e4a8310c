"""Octahedral mapping (Cigolle et al. 2014) and the bordered probe-map layout: oracles are closed-form
round trips, a Monte-Carlo estimate of texel solid angles, the explicit DDGI border formula, and
continuity of bilinear filtering across the octahedral folds."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import (
    add_border,
    border_index,
    fill_border,
    jittered_texel_directions,
    oct_decode,
    oct_encode,
    oct_wrap,
    sample_bilinear,
    sample_nearest,
    strip_border,
    surfel_texels,
    texel_directions,
    texel_of_direction,
    texel_solid_angles,
)


def _random_dirs(key, n, dtype=jnp.float64):
    d = jax.random.normal(key, (n, 3), dtype)
    return d / jnp.linalg.norm(d, axis=-1, keepdims=True)


def test_round_trip_float64(getkey):
    d = _random_dirs(getkey(), 20_000)
    uv = oct_encode(d)
    assert float(jnp.max(jnp.abs(uv))) <= 1.0
    # Upper hemisphere inside the diamond |u| + |v| <= 1, lower outside it.
    l1 = jnp.sum(jnp.abs(uv), axis=-1)
    assert bool(jnp.all(jnp.where(d[:, 2] >= 0, l1 <= 1 + 1e-12, l1 >= 1 - 1e-12)))
    back = oct_decode(uv)
    assert float(jnp.max(jnp.abs(back - d))) < 100 * jnp.finfo(jnp.float64).eps


def test_float32_in_float32_out(getkey):
    d = _random_dirs(getkey(), 100, jnp.float32)
    assert oct_encode(d).dtype == jnp.float32
    assert oct_decode(oct_encode(d)).dtype == jnp.float32
    assert texel_directions(8).dtype == jnp.float32


@pytest.mark.parametrize("res", [4, 16])
def test_solid_angles_sum_to_sphere_and_match_monte_carlo(res, getkey):
    omega = np.asarray(texel_solid_angles(res, jnp.float64, sub=8))
    assert omega.sum() == pytest.approx(4 * np.pi, rel=1e-4)
    n = 400_000
    d = _random_dirs(getkey(), n)
    rc = np.asarray(jax.vmap(lambda x: texel_of_direction(res, x))(d))
    counts = np.zeros((res, res))
    np.add.at(counts, (rc[:, 0], rc[:, 1]), 1)
    expected = n * omega / (4 * np.pi)
    z = (counts - expected) / np.sqrt(expected)  # binomial ≈ Poisson for small cells
    assert np.abs(z).max() < 5.5, f"texel solid angles disagree with uniform sampling (max |z| {z.max()})"


def test_wrap_lands_on_a_neighbouring_direction(getkey):
    # A point δ outside an edge must decode (after wrapping) to a direction O(δ) from the edge point.
    v = jax.random.uniform(getkey(), (500,), jnp.float64, -1, 1)
    delta = 1e-3
    for edge in (jnp.stack([1 + delta + 0 * v, v], -1), jnp.stack([v, -1 - delta + 0 * v], -1)):
        on_edge = jnp.clip(edge, -1, 1)
        ang = jnp.arccos(jnp.clip(jnp.sum(oct_decode(oct_wrap(edge)) * oct_decode(on_edge), -1), -1, 1))
        assert float(ang.max()) < 3 * delta


def _explicit_ddgi_border(res: int) -> tuple[np.ndarray, np.ndarray]:
    """Slow obvious reference: DDGI's border rule written out case by case (interior at 1..R)."""
    rows = np.zeros((res + 2, res + 2), int)
    cols = np.zeros((res + 2, res + 2), int)
    for r in range(res + 2):
        for c in range(res + 2):
            if 1 <= r <= res and 1 <= c <= res:
                pr, pc = r, c
            elif (r in (0, res + 1)) and (c in (0, res + 1)):  # corners: diagonally opposite corner
                pr, pc = (res if r == 0 else 1), (res if c == 0 else 1)
            elif r == 0:
                pr, pc = 1, res + 1 - c
            elif r == res + 1:
                pr, pc = res, res + 1 - c
            elif c == 0:
                pr, pc = res + 1 - r, 1
            else:
                pr, pc = res + 1 - r, res
            rows[r, c], cols[r, c] = pr - 1, pc - 1
    return rows, cols


@pytest.mark.parametrize("res", [2, 5, 8])
def test_border_matches_ddgi_layout(res):
    rows, cols = border_index(res)
    ref_r, ref_c = _explicit_ddgi_border(res)
    np.testing.assert_array_equal(np.asarray(rows), ref_r)
    np.testing.assert_array_equal(np.asarray(cols), ref_c)


def test_add_and_strip_border_round_trip(getkey):
    m = jax.random.normal(getkey(), (3, 6, 6, 2))
    b = add_border(m)
    assert b.shape == (3, 8, 8, 2)
    np.testing.assert_array_equal(np.asarray(strip_border(b)), np.asarray(m))
    with pytest.raises((ValueError, TypeError)):  # jaxtyping (tests) or our own check (users)
        add_border(m[:, :5])


@pytest.mark.parametrize("res", [2, 5, 8])
def test_fill_border_is_add_border_on_the_host(res):
    """``fill_border`` (the bake's host ring fill, in place) against ``add_border`` (every texel gathered):
    the same bordered maps, bit for bit, for maps without and with channels and of the bake's dtypes."""
    rng = np.random.default_rng(res)
    for interior in (
        rng.normal(size=(3, res, res)).astype(np.float32),
        rng.integers(-(2**15), 2**15, (3, res, res, 2)).astype(np.int16),
        rng.random((2, res, res)) < 0.5,
    ):
        bordered = np.zeros((len(interior), res + 2, res + 2, *interior.shape[3:]), interior.dtype)
        bordered[:, 1:-1, 1:-1] = interior
        channels = interior if interior.ndim == 4 else interior[..., None]
        want = np.asarray(add_border(jnp.asarray(channels)))
        got = fill_border(bordered)
        assert got is bordered and got.dtype == interior.dtype
        np.testing.assert_array_equal(got, want if interior.ndim == 4 else want[..., 0])


def test_bilinear_is_continuous_across_the_folds(getkey):
    # A map of a smooth function; (1-ε, v) and (1-ε, -v) are ~ε apart on the sphere (the fold), so the
    # filtered values must differ by O(ε), not by the texel-to-texel difference a clamped border gives.
    res = 8
    f = lambda d: jnp.stack([d[..., 0] + 2 * d[..., 1] + 3 * d[..., 2]], -1)
    bordered = add_border(f(texel_directions(res, jnp.float64)))
    clamped = jnp.pad(f(texel_directions(res, jnp.float64)), ((1, 1), (1, 1), (0, 0)), mode="edge")
    v = jax.random.uniform(getkey(), (200,), jnp.float64, 0.05, 0.95)
    eps = 1e-6
    a = oct_decode(jnp.stack([1 - eps + 0 * v, v], -1))
    b = oct_decode(jnp.stack([1 - eps + 0 * v, -v], -1))
    samp = jax.vmap(sample_bilinear, in_axes=(None, 0))
    gap = jnp.abs(samp(bordered, a) - samp(bordered, b))
    gap_clamped = jnp.abs(samp(clamped, a) - samp(clamped, b))
    assert float(gap.max()) < 1e-4
    assert float(gap_clamped.max()) > 0.1  # the test can fail: a wrong border is caught


def test_bilinear_reproduces_texel_centres_and_nearest_picks_the_texel(getkey):
    res = 8
    vals = jax.random.normal(getkey(), (res, res, 3))
    bordered = add_border(vals)
    dirs = texel_directions(res, jnp.float64).reshape(-1, 3)
    got = jax.vmap(sample_bilinear, in_axes=(None, 0))(bordered, dirs)
    np.testing.assert_allclose(np.asarray(got), np.asarray(vals).reshape(-1, 3), atol=1e-9)
    near = jax.vmap(sample_nearest, in_axes=(None, 0))(bordered, dirs)
    np.testing.assert_allclose(np.asarray(near), np.asarray(vals).reshape(-1, 3), atol=0)


def test_jittered_directions_stay_in_their_texel(getkey):
    res, n_sub = 6, 3
    d = jittered_texel_directions(res, n_sub, key=getkey(), dtype=jnp.float64)
    assert d.shape == (res, res, n_sub * n_sub, 3)
    rc = jax.vmap(lambda x: texel_of_direction(res, x))(d.reshape(-1, 3)).reshape(res, res, n_sub * n_sub, 2)
    ii, jj = np.meshgrid(np.arange(res), np.arange(res), indexing="ij")
    np.testing.assert_array_equal(np.asarray(rc[..., 0]), np.broadcast_to(ii[..., None], rc.shape[:3]))
    np.testing.assert_array_equal(np.asarray(rc[..., 1]), np.broadcast_to(jj[..., None], rc.shape[:3]))


@pytest.mark.parametrize("res,geo", [(4, 4), (4, 32), (8, 512), (64, 512), (16, 8), (8, 2), (2, 1024)])
def test_surfel_texel_holds_the_radiance_texels_centre(res, geo):
    """Oracle: the geometry texel's uv interval contains the radiance texel's centre, and a centre on a
    boundary between two texels (an even ratio) takes the upper one. The uv values are dyadic rationals,
    exact in float64."""
    idx = surfel_texels(res, geo)
    centre = (np.arange(res) + 0.5) * (2.0 / res) - 1.0
    lo, hi = idx * (2.0 / geo) - 1.0, (idx + 1) * (2.0 / geo) - 1.0
    assert idx.shape == (res,) and idx.min() >= 0 and idx.max() < geo
    assert np.all((lo <= centre) & (centre < hi))
    on_boundary = (centre - lo) == 0
    assert on_boundary.any() == (geo // res >= 2 and geo // res % 2 == 0)
