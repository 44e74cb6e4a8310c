"""Probe shading against closed forms and exact ray casting.

Oracles: (1) a constant-radiance environment, where every method must return E = π·L (normalised weights
of identical per-probe values; SH: the projection of a constant); (2) the SH projection of a linear
radiance a + b·ω_y, whose L2 irradiance is exactly πa + (2π/3)·b·n_y (R&H 2001: SH up to L1 reproduces a
linear function, and the cosine convolution of it is that closed form); (3) the Chebyshev weight's
closed form; (4) glossy probe radiance vs the exact hit: the probes are baked with a "position colour"
(reflected radiance = the hit point's normalised coordinates), so a ray read from the probes must carry
the colour of the point the exact caster hits, within a texel's footprint; (5) filtered reads: the
radiance MIP chain keeps ∫ L dω at every level and a consistent octahedral border, a read with a cone
wider than the sphere returns the sphere's mean, without a cone it is the bilinear read, and on the
position colour the bilinear read beats the one-texel read and the perfect trace (exact hit, probe that
sees it) reads the right colour.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import (
    ConfigError,
    LightFieldProbes,
    ProbeSet,
    add_border,
    pack_normal,
    sample_bilinear,
    sample_nearest,
    strip_border,
    texel_directions,
    texel_solid_angles,
)
from probeplace.geometry import BruteForceCaster
from probeplace.probes import (
    BakeConfig,
    TraceStatus,
    bake_probes,
    diffuse_irradiance,
    glossy_radiance,
    glossy_trace,
    make_tracer,
    perfect_trace_radiance,
    radiance_mips,
    sh_coefficients,
    sh_irradiance,
    shade_irradiance,
    trace_light_field,
)
from probeplace.probes._shade import _chebyshev
from probeplace.scene import build_scene, load_scene, make_materials
from probeplace.scene._primitives import box
from tests.geometry.raycast_reference import ray_triangle_t

ROOM_HI = np.array([4.0, 3.0, 5.0])
L_CONST = 0.7


def _grid(lo, hi, dims):
    axes = [(np.arange(n) + 0.5) / n for n in dims]
    g = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    return g * (np.asarray(hi) - np.asarray(lo)) + np.asarray(lo)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _in_front_of_a_surface(scene, o, d):
    """Rays whose origin is in free space as judged looking back along -d: every triangle the back ray
    meets first (float64, up to coplanar ties) faces the origin. Machine-independent: it never depends on
    which of two tied triangles a caster reports (the Cornell blocks stand on the floor with coplanar
    faces, where a caster's pick would decide whether a ray starting inside a block is kept)."""
    tris = np.asarray(scene.vertices, np.float64)[np.asarray(scene.faces)]
    n_t = len(tris)
    o64, back = np.asarray(o, np.float64), -np.asarray(d, np.float64)
    t = ray_triangle_t(
        np.tile(tris, (len(o64), 1, 1)), np.repeat(o64, n_t, 0), np.repeat(back, n_t, 0)
    ).reshape(len(o64), n_t)
    t_first = t.min(axis=1, keepdims=True)
    first = np.isfinite(t) & (t <= t_first + 1e-6 * np.maximum(1.0, t_first))  # the first hit and its ties
    ng = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    faces_origin = (back @ ng.T) < 0  # geometric normal against the back ray: seen from the front
    return np.isfinite(t_first[:, 0]) & np.all(~first | faces_origin, axis=1)


def _synthetic_lf(pos, res=16, far=20.0):
    """Probes in an open, constant environment, built by hand (no bake): reflected radiance L everywhere,
    every texel's surface at distance ``far`` (so every receiver is visible), irradiance π·L."""
    n = len(pos)
    ones = lambda *shape: jnp.ones((n, *shape), jnp.float32)
    return LightFieldProbes(
        pos_world=jnp.asarray(pos, jnp.float32),
        active=jnp.ones(n, bool),
        inside=jnp.zeros(n, bool),
        radiance=L_CONST * ones(res + 2, res + 2, 3),
        emission=0.0 * ones(res + 2, res + 2, 3),
        normal16=pack_normal(0.0 * ones(res + 2, res + 2, 3)),
        distance=far * ones(res + 2, res + 2),
        irradiance=np.pi * L_CONST * ones(6, 6, 3),
        moments=jnp.concatenate([far * ones(10, 10, 1), far * far * ones(10, 10, 1)], axis=-1),
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
    free = _in_front_of_a_surface(scene, o, d)
    o32, d32 = o32[np.flatnonzero(free)[:n]], d32[np.flatnonzero(free)[:n]]
    tr = make_tracer(lf, scene.bounds)
    rad, status = glossy_radiance(tr, lf, o32, d32, include_emission=False)
    rad, status = np.asarray(rad, np.float64), np.asarray(status)
    exact = caster.closest_hit(o32, d32)
    xe = np.asarray(o32, np.float64) + np.asarray(exact.t, np.float64)[:, None] * np.asarray(d32, np.float64)
    want = (xe - lo) / (hi - lo)
    hit = status == TraceStatus.HIT
    assert np.mean(status == TraceStatus.UNRESOLVED) < 0.05
    # A probe texel averages the colour over its footprint: 4π/64² sr at up to the box diagonal; in
    # normalised colour that is ≲ 0.05 per axis at the far walls. Allow 0.08, 97% of hits (texels that
    # straddle an edge between two surfaces carry a blend).
    err = np.max(np.abs(rad - want), axis=1)
    resolved = status != TraceStatus.UNRESOLVED
    exact_hit = np.asarray(exact.tri) >= 0  # the box is open toward the camera: misses are real
    assert np.mean(hit[resolved] == exact_hit[resolved]) > 0.97
    assert np.mean(err[hit] < 0.08) > 0.97
    rad_e, _ = glossy_radiance(tr, lf, o32, d32, include_emission=True)
    np.testing.assert_allclose(np.asarray(rad_e)[hit], rad[hit] + 0.25, atol=1e-6)


# ------------------------------------------------------------------------------- filtered reads
def _random_radiance_lf(res=16, seed=3):
    """The room's probes with random radiance (a properly bordered map) and surfaces at ``far``."""
    lo, hi = np.zeros(3), ROOM_HI
    lf = _synthetic_lf(_grid(lo, hi, (2, 2, 2)), res=res)
    rng = np.random.default_rng(seed)
    rad = add_border(jnp.asarray(rng.uniform(0.0, 2.0, (8, res, res, 3)), jnp.float32))
    return eqx.tree_at(lambda m: m.radiance, lf, rad)


def test_radiance_mips_keep_integral_and_border():
    lf = _random_radiance_lf()
    levels = radiance_mips(lf)
    assert [m.shape[1] for m in levels] == [18, 10, 6, 4, 3]
    np.testing.assert_array_equal(np.asarray(levels[0]), np.asarray(lf.radiance))
    w = np.asarray(texel_solid_angles(16), np.float64)
    want = np.einsum("ij,pijc->pc", w, np.asarray(strip_border(lf.radiance), np.float64))
    for m in levels:
        inner = np.asarray(strip_border(m), np.float64)
        r = inner.shape[1]
        wk = w.reshape(r, 16 // r, r, 16 // r).sum(axis=(1, 3))  # the level's texel solid angles
        # ∫ L dω is preserved exactly up to float32 rounding of the averages.
        np.testing.assert_allclose(np.einsum("ij,pijc->pc", wk, inner), want, rtol=1e-5)
        np.testing.assert_array_equal(np.asarray(add_border(strip_border(m))), np.asarray(m))


def _floor_rays(n, seed=0):
    """Rays from above the floor of the room down to it: every probe of the 2×2×2 room grid is on the
    floor's lit side (y > 0), and the synthetic surfaces at ``far`` never hide the hit."""
    rng = np.random.default_rng(seed)
    x = np.stack([rng.uniform(0.2, 3.8, n), np.zeros(n), rng.uniform(0.2, 4.8, n)], axis=1)
    o = np.stack([rng.uniform(0.2, 3.8, n), np.full(n, 2.5), rng.uniform(0.2, 4.8, n)], axis=1)
    d = _unit(x - o)
    t = np.linalg.norm(x - o, axis=1)
    nrm = np.tile([0.0, 1.0, 0.0], (n, 1))
    f32 = lambda a: jnp.asarray(a, jnp.float32)
    return f32(o), f32(d), f32(t), f32(nrm), x


def test_filtered_reads_closed_forms():
    lf = _random_radiance_lf()
    o, d, t, nrm, x = _floor_rays(64)
    read = lambda **kw: perfect_trace_radiance(lf, o, d, t, nrm, **kw)
    bil, tex = read(filter="bilinear"), read(filter="texel")
    assert not bool(jnp.any(bil.fallback))
    p = np.asarray(bil.probe)
    pos = np.asarray(lf.pos_world, np.float64)
    # The nearest probe sees every floor point here, and the read is by the direction probe → hit.
    np.testing.assert_array_equal(p, np.argmin(np.linalg.norm(x[:, None] - pos[None], axis=-1), axis=1))
    w = jnp.asarray(_unit(x - pos[p]), jnp.float32)
    want_bil = jax.vmap(sample_bilinear)(lf.radiance[p], w)
    want_tex = jax.vmap(sample_nearest)(lf.radiance[p], w)
    np.testing.assert_allclose(np.asarray(bil.radiance), np.asarray(want_bil), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(np.asarray(tex.radiance), np.asarray(want_tex), rtol=1e-6)
    # "mip" without a cone is level 0, i.e. bilinear; with a cone wider than the sphere it is the top
    # level: the probe's mean radiance over the sphere, ∫ L dω / 4π.
    # (rtol: float32 rounding of the level blend, a few eps)
    np.testing.assert_allclose(np.asarray(read(filter="mip").radiance), np.asarray(bil.radiance), rtol=1e-5)
    wide = read(filter="mip", cone=1e6)
    sa = np.asarray(texel_solid_angles(16), np.float64)
    mean = np.einsum("ij,pijc->pc", sa, np.asarray(strip_border(lf.radiance), np.float64)) / sa.sum()
    np.testing.assert_allclose(np.asarray(wide.radiance), mean[p], rtol=1e-4)
    assert float(jnp.min(wide.lod)) >= 4.0
    # A level between two levels blends them linearly: lod grows with the cone by ½ log₂.
    c1, c4 = read(filter="mip", cone=1e-2), read(filter="mip", cone=4e-2)
    l1, l4 = np.asarray(c1.lod), np.asarray(c4.lod)
    inner = (l1 > 0) & (l4 < 4.0)  # away from the clamps at level 0 and the top level
    assert inner.sum() > 20
    np.testing.assert_allclose(l4[inner], l1[inner] + 1.0, atol=1e-4)
    with pytest.raises(ConfigError):
        read(filter="trilinear")
    with pytest.raises(ConfigError):
        read(choose="best")


def _cornell_coloured(colour_of_hit):
    """27 probes at 32² of the Cornell box whose radiance is ``colour_of_hit(hit, o, d, lo, ext)`` (float32)
    at each texel ray's exact hit, and 800 rays in front of a surface with their exact hits: (scene, lf,
    origins, directions, exact hits, lo, ext)."""
    scene = load_scene("cornell_box")
    caster = BruteForceCaster(scene)
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    probes = ProbeSet(pos_world=jnp.asarray(_grid(lo, hi, (3, 3, 3)), jnp.float32), active=jnp.ones(27, bool))
    lo32, ext32 = jnp.asarray(lo, jnp.float32), jnp.asarray(hi - lo, jnp.float32)

    def colour(o, d, k):
        h = caster.closest_hit(o, d)
        c = colour_of_hit(h, o, d, lo32, ext32)
        return jnp.where((h.tri >= 0)[:, None], c, 0.0).astype(o.dtype), 0.0 * o

    cfg = BakeConfig(
        radiance_res=32, irradiance_res=4, moments_res=4, n_sub=2, probes_per_batch=27, progress=False
    )
    lf = bake_probes(scene, probes, caster=caster, radiance_fn=colour, key=jax.random.key(0), config=cfg)
    rng = np.random.default_rng(4)
    n = 800
    o = rng.uniform(lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo), (3 * n, 3))
    d = _unit(rng.normal(size=(3 * n, 3)))
    o32, d32 = jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32)
    free = _in_front_of_a_surface(scene, o, d)
    keep = np.flatnonzero(free)[:n]
    o32, d32 = o32[keep], d32[keep]
    exact = caster.closest_hit(o32, d32)
    return scene, lf, o32, d32, exact, lo, hi - lo


def _facing(n, d):
    """Normals ``n`` turned toward the rays' origins (against ``d``)."""
    return jnp.where((jnp.sum(n * d, axis=-1) > 0)[:, None], -n, n)


@pytest.fixture(scope="module")
def cornell_colour_small():
    """27 probes at 32² with the position colour (the cheap sibling of ``cornell_position_colour``)."""
    position = lambda h, o, d, lo, ext: (
        (o + jnp.where(h.tri >= 0, h.t, 0.0)[:, None] * d - lo[None]) / ext[None]
    )
    scene, lf, o, d, exact, lo, ext = _cornell_coloured(position)
    xe = np.asarray(o, np.float64) + np.asarray(exact.t, np.float64)[:, None] * np.asarray(d, np.float64)
    return scene, lf, o, d, exact, (xe - lo) / ext


@pytest.fixture(scope="module")
def cornell_normal_colour():
    """27 probes at 32² whose radiance is the hit's geometric normal, turned toward the probe, as a colour
    ((n + 1) / 2): each face of the box's walls and blocks its own colour, so a read that blends two
    faces is wrong by the difference of their normals."""
    normal = lambda h, o, d, lo, ext: 0.5 * (_facing(h.geo_normal, d) + 1.0)
    scene, lf, o, d, exact, _, _ = _cornell_coloured(normal)
    return scene, lf, o, d, exact, np.asarray(0.5 * (_facing(exact.geo_normal, d) + 1.0), np.float64)


def test_perfect_trace_reads_the_hit_colour(cornell_colour_small):
    _, lf, o, d, exact, want = cornell_colour_small
    hit = np.asarray(exact.tri) >= 0
    t = jnp.where(exact.tri >= 0, exact.t, jnp.inf)
    errs = {}
    for f in ("texel", "bilinear", "depth_aware"):
        r = perfect_trace_radiance(lf, o, d, t, exact.geo_normal, filter=f)
        rad = np.asarray(r.radiance, np.float64)
        assert np.all(rad[~hit] == 0) and np.all(np.asarray(r.probe)[~hit] == -1)
        # Some probe of the 3×3×3 grid sees nearly every point of the box (a fallback is a point seen
        # by none of the 8 nearest, e.g. in a crevice under a block).
        assert np.mean(np.asarray(r.fallback)[hit]) < 0.02
        errs[f] = np.max(np.abs(rad - want), axis=1)[hit]
    # A 32² texel spans ≲ 0.1 of the normalised colour at the far walls; texels straddling two surfaces
    # blend them, hence 90% and not all.
    assert np.mean(errs["texel"] < 0.1) > 0.9 and np.mean(errs["bilinear"] < 0.1) > 0.9
    # Position colour is linear on each surface: bilinear reconstruction beats the one-texel read.
    assert errs["bilinear"].mean() < errs["texel"].mean()
    # Depth-aware: where the four texels straddle a silhouette, only those whose surfel lies at the hit
    # are blended, so the large errors (a far wall's colour read on a block's edge) shrink; on one
    # surface it is the bilinear read.
    da, bil = errs["depth_aware"], errs["bilinear"]
    assert np.mean(da < 0.1) >= np.mean(bil < 0.1)
    assert np.quantile(da, 0.99) < np.quantile(bil, 0.99), (np.quantile(da, 0.99), np.quantile(bil, 0.99))
    assert np.median(np.abs(da - bil)) < 1e-6  # most reads see one surface: identical


@pytest.mark.isa  # counts of reads above a threshold, under every instruction set
def test_depth_normal_read_keeps_to_the_hit_surface(cornell_normal_colour):
    """The normal test of ``"depth_normal"`` against ``"depth_aware"`` alone, on the exact hits (the perfect
    trace, so the tracer plays no part): where a read's four texels span two faces of a crease or an
    edge whose planes both pass within the depth tolerance of the hit, the depth test blends the two
    faces' colours; the texels that face as the hit's surface does hold its own. Oracle: the hit's
    normal colour."""
    _, lf, o, d, exact, want = cornell_normal_colour
    hit = np.asarray(exact.tri) >= 0
    t = jnp.where(exact.tri >= 0, exact.t, jnp.inf)
    errs = {}
    for f in ("depth_aware", "depth_normal"):
        r = perfect_trace_radiance(lf, o, d, t, exact.geo_normal, filter=f)
        errs[f] = np.max(np.abs(np.asarray(r.radiance, np.float64) - want), axis=1)[hit]
    da, dn = errs["depth_aware"], errs["depth_normal"]
    # Two faces' colours differ by 0.5 in a channel (axis-aligned normals): an error above 0.2 is a read
    # that blends in 40 % of another face (measured 10 reads of 654 with the depth test alone, 4 with the
    # normal test; what stays is the bake's own blend: a texel's 2×2 jittered rays straddle an edge).
    assert np.sum(dn > 0.2) <= np.sum(da > 0.2) / 2, (np.sum(dn > 0.2), np.sum(da > 0.2))
    assert dn.mean() < da.mean()
    assert np.median(np.abs(dn - da)) < 1e-6  # most reads see one face: the same read


@pytest.mark.slow  # ~25 s; the filters stay in the default run via test_filtered_reads_closed_forms
def test_glossy_texel_filter_is_the_resolved_texel(cornell_colour_small):
    scene, lf, o, d, _, want = cornell_colour_small
    tr = make_tracer(lf, scene.bounds)
    if tr.res != lf.radiance_res:
        pytest.skip("the tracer's maps are not the radiance map's resolution")
    res = trace_light_field(tr, o, d)
    g = glossy_trace(tr, lf, o, d, filter="texel", include_emission=False)
    hit = np.asarray(res.status) == TraceStatus.HIT
    np.testing.assert_array_equal(np.asarray(g.status), np.asarray(res.status))
    p, tx = np.asarray(res.probe)[hit], np.asarray(res.texel)[hit]
    old = np.asarray(lf.radiance)[p, tx[:, 0] + 1, tx[:, 1] + 1]
    # The hit lies in its texel's cone, so reading by direction finds the same texel (bar rounding on
    # texel edges).
    same = np.all(np.asarray(g.radiance)[hit] == old, axis=1)
    assert same.mean() > 0.99
    b = glossy_trace(tr, lf, o, d, filter="bilinear", include_emission=False)
    both = hit & np.all(np.isfinite(want), axis=1)  # the exact caster hits too (the box is open)
    err = lambda r: np.max(np.abs(np.asarray(r.radiance, np.float64)[both] - want[both]), axis=1).mean()
    assert err(b) < err(g)
