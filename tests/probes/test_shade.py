"""Probe shading against closed forms and exact ray casting.

Oracles: (1) a constant-radiance environment, where every method must return E = π·L (normalised weights
of identical per-probe values; SH: the projection of a constant); (2) the SH projection of a linear
radiance a + b·ω_y, whose L2 irradiance is exactly πa + (2π/3)·b·n_y (R&H 2001: SH up to L1 reproduces a
linear function, and the cosine convolution of it is that closed form); (3) the Chebyshev weight's
closed form; (4) glossy probe radiance vs the exact hit: the probes are baked with a "position colour"
(reflected radiance = the hit point's normalised coordinates), so a ray read from the probes must carry
the colour of the point the exact caster hits, within a texel's footprint.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import ConfigError, LightFieldProbes, ProbeSet, add_border, texel_directions
from probeplace.geometry import BruteForceCaster
from probeplace.probes import (
    BakeConfig,
    bake_probes,
    diffuse_irradiance,
    glossy_radiance,
    make_tracer,
    sh_coefficients,
    sh_irradiance,
    shade_irradiance,
)
from probeplace.probes._shade import _chebyshev
from probeplace.probes._trace import RAY_HIT, RAY_UNRESOLVED
from probeplace.scene import build_scene, load_scene, make_materials
from probeplace.scene._primitives import box

ROOM_HI = np.array([4.0, 3.0, 5.0])
L_CONST = 0.7


def _grid(lo, hi, dims):
    axes = [(np.arange(n) + 0.5) / n for n in dims]
    g = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    return g * (np.asarray(hi) - np.asarray(lo)) + np.asarray(lo)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _synthetic_lf(pos, res=16, far=20.0):
    """Probes in an open, constant environment, built by hand (no bake): reflected radiance L everywhere,
    every texel's surface at distance ``far`` (so every receiver is visible), irradiance π·L."""
    n = len(pos)
    ones = lambda *shape: jnp.ones((n, *shape), jnp.float32)
    mips = tuple(far * ones(res >> k, res >> k) for k in range(1, res.bit_length()))
    return LightFieldProbes(
        pos_world=jnp.asarray(pos, jnp.float32),
        active=jnp.ones(n, bool),
        inside=jnp.zeros(n, bool),
        radiance=L_CONST * ones(res + 2, res + 2, 3),
        emission=0.0 * ones(res + 2, res + 2, 3),
        normal=0.0 * ones(res + 2, res + 2, 3),
        distance=far * ones(res + 2, res + 2),
        irradiance=np.pi * L_CONST * ones(6, 6, 3),
        moments=jnp.concatenate([far * ones(10, 10, 1), far * far * ones(10, 10, 1)], axis=-1),
        distance_min_mips=mips,
        distance_max_mips=mips,
        far=jnp.float32(far),
    )


@pytest.fixture(scope="module")
def room_lf():
    """2×2×2 probes over a 4×3×5 box, constant environment (a scene only for its bounds)."""
    v, f = box(np.zeros(3), ROOM_HI)
    mats = make_materials(["wall"], np.array([[0.5, 0.5, 0.5]]))
    scene = build_scene("empty_room", v, f[:, ::-1], np.zeros(len(f), int), mats)
    return scene, _synthetic_lf(_grid(np.zeros(3), ROOM_HI, (2, 2, 2)))


@pytest.fixture(scope="module")
def scattered_lf():
    """The same environment seen by 12 scattered probes (a non-uniform set: voxel index, inverse distance)."""
    rng = np.random.default_rng(7)
    return _synthetic_lf(rng.uniform(0.3, ROOM_HI - 0.3, (12, 3)))


def _points(n, seed=0):
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.2, ROOM_HI - 0.2, (n, 3))
    nrm = _unit(rng.normal(size=(n, 3)))
    return jnp.asarray(x, jnp.float32), jnp.asarray(nrm, jnp.float32)


@pytest.mark.parametrize("method", ["lightfield", "irradiance", "sh"])
def test_constant_environment_gives_pi_L(room_lf, scattered_lf, method):
    # The irradiance maps hold π·L exactly (a baked map is a quadrature of it, tested with the bake), so
    # this checks the interpolation alone: normalised weights of equal values return that value.
    scene, lf = room_lf
    x, n = _points(200)
    e = np.asarray(shade_irradiance(lf, x, n, method=method, bounds=scene.bounds), np.float64)
    e2 = np.asarray(shade_irradiance(scattered_lf, x, n, method=method, bounds=scene.bounds), np.float64)
    e = np.concatenate([e, e2])
    assert e.shape == (400, 3)
    if method == "sh":
        # SH: c_00 = L·Y00·Σ Δω is exact, but the l ≥ 1 coefficients of a constant are midpoint
        # quadratures of ∫ Y_lm = 0 over 16² texels, and Y00 is given to 6 digits: 1e-3 relative.
        np.testing.assert_allclose(e, np.pi * L_CONST, rtol=1e-3)
    else:
        np.testing.assert_allclose(e, np.pi * L_CONST, rtol=10 * np.finfo(np.float32).eps)


def test_shading_keeps_float32(room_lf):
    _, lf = room_lf
    x, n = _points(10)
    for m in ("lightfield", "irradiance", "sh"):
        assert shade_irradiance(lf, x, n, method=m).dtype == jnp.float32
    with pytest.raises(ConfigError):
        shade_irradiance(lf, x, n, method="nope")


def test_sh_projection_of_linear_radiance_closed_form(room_lf):
    _, lf = room_lf
    a, b = 0.6, 0.35
    res = lf.radiance_res
    dirs = texel_directions(res, jnp.float32)
    rad = (a + b * dirs[..., 1:2]) * jnp.ones((1, 1, 3), jnp.float32)
    lf = eqx.tree_at(lambda m: m.radiance, lf, jnp.broadcast_to(add_border(rad)[None], lf.radiance.shape))
    c = np.asarray(sh_coefficients(lf), np.float64)[0, :, 0]
    # c_00 = a·Y00·4π, c_1-1 = b·0.488603·4π/3 (∫ y² dω = 4π/3), the rest 0, up to
    # the midpoint quadrature over 16² texels (|error| ≈ 3e-3 on Y20).
    np.testing.assert_allclose(c[0], a * 0.282095 * 4 * np.pi, rtol=1e-4)
    np.testing.assert_allclose(c[1], b * 0.488603 * 4 * np.pi / 3, rtol=2e-3)
    assert np.all(np.abs(c[2:]) < 5e-3)
    x, n = _points(100, seed=3)
    e = np.asarray(sh_irradiance(lf, x, n), np.float64)[:, 0]
    expect = np.pi * a + 2 * np.pi / 3 * b * np.asarray(n, np.float64)[:, 1]
    np.testing.assert_allclose(e, expect, rtol=3e-3, atol=3e-3)


def test_chebyshev_weight_closed_form():
    mean, mean2 = 2.0, 4.5  # σ² = 0.5
    m = jnp.broadcast_to(jnp.asarray([mean, mean2], jnp.float32), (6, 6, 2))
    d = jnp.asarray([0.3, -0.5, 0.8], jnp.float32)
    d = d / jnp.linalg.norm(d)
    # Receiver closer than the mean occluder distance: fully visible.
    assert float(_chebyshev(m, 1.0 * d)) == 1.0
    assert float(_chebyshev(m, 1.999 * d)) == 1.0
    # Farther: σ²/(σ² + (r − μ)²), cubed (DDGI), floored at 0.05.
    r = 2.3
    cheb = 0.5 / (0.5 + (r - mean) ** 2)
    np.testing.assert_allclose(float(_chebyshev(m, r * d)), max(cheb**3, 0.05), rtol=1e-5)
    assert float(_chebyshev(m, 3.0 * d)) == pytest.approx(0.05)


def test_plain_blend_is_trilinear(room_lf):
    """visibility=False is the plain trilinear blend: at a probe's position it returns that probe's own
    irradiance, whatever its neighbours hold."""
    _, lf = room_lf
    rng = np.random.default_rng(5)
    irr = jnp.asarray(rng.uniform(0.5, 2.0, lf.irradiance.shape[:1]), jnp.float32)
    lf = eqx.tree_at(lambda m: m.irradiance, lf, irr[:, None, None, None] * jnp.ones_like(lf.irradiance))
    x = lf.pos_world
    n = jnp.broadcast_to(jnp.asarray([0.0, 1.0, 0.0], jnp.float32), x.shape)
    e = np.asarray(diffuse_irradiance(lf, x, n, visibility=False), np.float64)[:, 0]
    np.testing.assert_allclose(e, np.asarray(irr, np.float64), rtol=1e-5)


# ------------------------------------------------------------------------------- glossy radiance
@pytest.fixture(scope="module")
def cornell_position_colour():
    scene = load_scene("cornell_box")
    caster = BruteForceCaster(scene)
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    pos = _grid(lo, hi, (4, 4, 4))
    probes = ProbeSet(pos_world=jnp.asarray(pos, jnp.float32), active=jnp.ones(len(pos), bool))
    lo32, ext32 = jnp.asarray(lo, jnp.float32), jnp.asarray(hi - lo, jnp.float32)

    def colour(o, d, k):
        h = caster.closest_hit(o, d)
        x = o + jnp.where(h.tri >= 0, h.t, 0.0)[:, None] * d
        c = jnp.where((h.tri >= 0)[:, None], (x - lo32[None]) / ext32[None], 0.0)
        return c.astype(o.dtype), jnp.full_like(o, 0.25)

    cfg = BakeConfig(
        radiance_res=64, irradiance_res=4, moments_res=4, n_sub=1, probes_per_batch=64, progress=False
    )
    lf = bake_probes(scene, probes, caster=caster, radiance_fn=colour, key=jax.random.key(0), config=cfg)
    return scene, caster, lf, lo, hi


@pytest.mark.slow  # a 64-probe bake at 64² plus the tracer's compile: ~35 s on 2 cores
def test_glossy_radiance_matches_exact_hit(cornell_position_colour):
    scene, caster, lf, lo, hi = cornell_position_colour
    rng = np.random.default_rng(2)
    n = 1500
    # Rays from random interior points in random directions (origins outside the boxes).
    o = rng.uniform(lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo), (3 * n, 3))
    d = _unit(rng.normal(size=(3 * n, 3)))
    o32, d32 = jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32)
    back = caster.closest_hit(o32, -d32)
    free = np.asarray(back.tri) >= 0
    free &= np.sum(np.asarray(back.geo_normal) * (-d), axis=1) < 0  # the point is in front of a surface
    o32, d32 = o32[np.flatnonzero(free)[:n]], d32[np.flatnonzero(free)[:n]]
    tr = make_tracer(lf, scene.bounds)
    rad, status = glossy_radiance(tr, lf, o32, d32, include_emission=False)
    rad, status = np.asarray(rad, np.float64), np.asarray(status)
    exact = caster.closest_hit(o32, d32)
    xe = np.asarray(o32, np.float64) + np.asarray(exact.t, np.float64)[:, None] * np.asarray(d32, np.float64)
    want = (xe - lo) / (hi - lo)
    hit = status == RAY_HIT
    assert np.mean(status == RAY_UNRESOLVED) < 0.05
    # A probe texel averages the colour over its footprint: 4π/64² sr at up to the box diagonal; in
    # normalised colour that is ≲ 0.05 per axis at the far walls. Allow 0.08, 97% of hits (texels that
    # straddle an edge between two surfaces carry a blend).
    err = np.max(np.abs(rad - want), axis=1)
    resolved = status != RAY_UNRESOLVED
    exact_hit = np.asarray(exact.tri) >= 0  # the box is open toward the camera: misses are real
    assert np.mean(hit[resolved] == exact_hit[resolved]) > 0.97
    assert np.mean(err[hit] < 0.08) > 0.97
    rad_e, _ = glossy_radiance(tr, lf, o32, d32, include_emission=True)
    np.testing.assert_allclose(np.asarray(rad_e)[hit], rad[hit] + 0.25, atol=1e-6)
