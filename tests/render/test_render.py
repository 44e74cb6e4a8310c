"""Path tracer tests: closed-form furnaces for every light type and component, invariances, caster, I/O."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace.geometry import AbstractRayCaster, BruteForceCaster
from probeplace.render import (
    COMPONENTS,
    RenderConfig,
    load_exr,
    render,
    save_render,
    trace_rays,
)
from probeplace.scene import build_scene, make_camera, make_materials, make_sun

_QUADS = {  # unit cube faces, any winding (fixed below to face the centre)
    "x0": [(0, 0, 0), (0, 1, 0), (0, 1, 1), (0, 0, 1)],
    "x1": [(1, 0, 0), (1, 1, 0), (1, 1, 1), (1, 0, 1)],
    "y0": [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)],
    "y1": [(0, 1, 0), (1, 1, 0), (1, 1, 1), (0, 1, 1)],
    "z0": [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)],
    "z1": [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)],
}


# 64 items × 8 samples per batch: tests on the Cornell box share one compiled kernel (compiles dominate).
_PPB = 512


def _furnace_box(albedo: float, le: float):
    """A closed unit cube, every wall Lambertian with ``albedo`` and emitting ``le`` inward."""
    verts, faces = [], []
    for quad in _QUADS.values():
        q = np.asarray(quad, np.float64)
        n = np.cross(q[1] - q[0], q[2] - q[0])
        if np.dot(n, 0.5 - q.mean(axis=0)) < 0:
            q = q[[0, 3, 2, 1]]
        b = len(verts) * 4
        verts.append(q)
        faces += [[b, b + 1, b + 2], [b, b + 2, b + 3]]
    mats = make_materials(["wall"], base_color=np.full((1, 3), albedo), emission=np.full((1, 3), le))
    cam = make_camera((0.5, 0.5, 0.2), (0.5, 0.45, 1.0), 90.0, "inside")
    return build_scene(
        "furnace", np.concatenate(verts), np.asarray(faces), np.zeros(12, int), mats, views=(cam,)
    )


def _floor(sky, sun=None):
    """A large Lambertian floor (albedo 0.5) seen from above; every floor point sees the whole sky."""
    v = np.array([[-100, 0, -100], [100, 0, -100], [100, 0, 100], [-100, 0, 100]], np.float64)
    f = np.array([[0, 2, 1], [0, 3, 2]])  # counter-clockwise seen from +y
    mats = make_materials(["floor"], base_color=np.full((1, 3), 0.5))
    cam = make_camera((0.0, 1.0, 0.0), (0.0, 0.0, 0.01), 60.0, "down")
    return build_scene("floor", v, f, np.zeros(2, int), mats, views=(cam,), sun=sun, sky_radiance=sky)


def _check_mean(res, comp, expected, n_sigma=5.0):
    img = np.asarray(res.image(comp), np.float64)
    var = np.asarray(res.variance(comp), np.float64)
    mean = img.mean(axis=(0, 1))
    se = np.sqrt(var.sum(axis=(0, 1))) / (img.shape[0] * img.shape[1])
    tol = n_sigma * se + 1e-5 * np.abs(expected)  # 1e-5: float32 accumulation within one path
    assert np.all(np.abs(mean - expected) <= tol), (comp, mean, expected, se)


@pytest.mark.parametrize("max_depth", [1, 2, 4])
def test_furnace_box_closed_form(max_depth):
    # Closed cube, uniform emission Le and albedo ρ: radiance everywhere = Le Σ_{k<D} ρ^k (D segments).
    # Components by definition: emission = Le, direct = ρ Le, indirect = Le Σ_{2≤k<D} ρ^k, all diffuse.
    rho, le = 0.6, 1.0
    scene = _furnace_box(rho, le)
    cfg = RenderConfig(
        width=8, height=8, spp=256, max_depth=max_depth, rr_depth=3, specular=0.0, progress=False
    )
    res = render(scene, "inside", cfg, key=jax.random.key(0))
    e = np.full(3, le)
    _check_mean(res, "emission", e)
    _check_mean(res, "direct", e * rho if max_depth >= 2 else 0 * e)
    ind = sum(rho**k for k in range(2, max_depth)) * e
    _check_mean(res, "diffuse_indirect", ind)
    _check_mean(res, "glossy_indirect", 0 * e)
    _check_mean(res, "full", sum(rho**k for k in range(max_depth)) * e)
    # Components add up to the full image sample by sample.
    total = sum(res.image(c) for c in ("emission", "direct", "diffuse_indirect", "glossy_indirect"))
    np.testing.assert_allclose(total, res.image("full"), rtol=1e-5, atol=1e-6)


def test_sky_and_sun_closed_form():
    # Lambertian floor (ρ = 0.5) under a constant sky L_s and a sun disk of radiance L_sun, angular radius
    # r at zenith angle θ: reflected radiance = ρ (L_s + L_sun sin²r cos θ) (uniform disk irradiance
    # π sin²r L_sun cos θ, disk fully above the horizon). All of it is "direct".
    r, theta = 0.08, 0.6
    sun = make_sun((np.sin(theta), np.cos(theta), 0.0), (40.0, 20.0, 10.0), angular_radius=r)
    sky = (0.2, 0.3, 0.5)
    scene = _floor(sky, sun)
    cfg = RenderConfig(width=8, height=8, spp=512, max_depth=3, progress=False)
    res = render(scene, "down", cfg, key=jax.random.key(1))
    expected = 0.5 * (np.asarray(sky) + np.asarray([40.0, 20.0, 10.0]) * np.sin(r) ** 2 * np.cos(theta))
    cfg0 = RenderConfig(width=8, height=8, spp=512, max_depth=3, specular=0.0, progress=False)
    res0 = render(scene, "down", cfg0, key=jax.random.key(1))
    _check_mean(res0, "direct", expected)
    _check_mean(res0, "emission", np.zeros(3))
    _check_mean(res0, "diffuse_indirect", np.zeros(3))
    # With the glTF dielectric specular lobe the floor reflects a bit less diffusely and a bit of
    # glossy; energy stays below the Lambert value plus Fresnel's 4 %.
    full = np.asarray(res.image("full")).mean(axis=(0, 1))
    assert np.all(full > 0.8 * expected) and np.all(full < 1.1 * expected)


@pytest.mark.isa
@pytest.mark.slow  # ~35 s; chunking stays in the default run via test_trace_rays_chunks_and_offsets
def test_batching_does_not_change_the_image(cornell):
    # Random numbers are a function of (pixel, sample, bounce): batching is invisible (common random numbers).
    a = RenderConfig(width=8, height=8, spp=8, max_depth=5, progress=False, paths_per_batch=_PPB)
    b = RenderConfig(width=8, height=8, spp=8, max_depth=5, progress=False, paths_per_batch=64)
    ra = render(cornell, "front", a, key=jax.random.key(3))
    rb = render(cornell, "front", b, key=jax.random.key(3))
    np.testing.assert_allclose(ra.mean, rb.mean, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(ra.var_of_mean, rb.var_of_mean, rtol=1e-3, atol=1e-8)
    assert ra.mean.dtype == jnp.float32


class _HostCaster(AbstractRayCaster):
    """Wraps a caster behind NumPy round trips: not traceable, so render takes its host bounce loop."""

    inner: BruteForceCaster
    jittable = False

    def closest_hit(self, origins, directions, t_max=jnp.inf):
        hit = self.inner.closest_hit(jnp.asarray(np.asarray(origins)), jnp.asarray(np.asarray(directions)))
        return jax.tree.map(lambda x: jnp.asarray(np.asarray(x)), hit)

    def occluded(self, origins, directions, t_max):
        return jnp.asarray(self.occluded_host(origins, directions, t_max))

    def occluded_host(self, origins, directions, t_max):
        return self.inner.occluded_host(origins, directions, t_max)


@pytest.mark.isa
@pytest.mark.slow  # ~35 s: two full renders of the Cornell box
def test_host_loop_matches_jitted_loop(cornell):
    cfg = RenderConfig(
        width=8, height=8, spp=4, max_depth=6, rr_depth=2, progress=False, paths_per_batch=_PPB
    )
    ra = render(cornell, "front", cfg, key=jax.random.key(4))
    rb = render(cornell, "front", cfg, key=jax.random.key(4), caster=_HostCaster(BruteForceCaster(cornell)))
    np.testing.assert_allclose(ra.mean, rb.mean, rtol=1e-4, atol=1e-5)


def test_trace_rays_chunks_and_offsets(cornell):
    # Tracing rays in two chunks with running stream offsets equals one call.
    cam = cornell.view("interior")
    n = 40
    d = jax.random.normal(jax.random.key(5), (n, 3), jnp.float32)
    d = d / jnp.linalg.norm(d, axis=1, keepdims=True)
    o = jnp.broadcast_to(cam.position, (n, 3))
    kw = dict(spp=16, key=7, max_depth=4, paths_per_batch=_PPB)
    full = trace_rays(cornell, o, d, **kw)
    a = trace_rays(cornell, o[:15], d[:15], **kw)
    b = trace_rays(cornell, o[15:], d[15:], stream_offset=15, **kw)
    np.testing.assert_allclose(full.mean, jnp.concatenate([a.mean, b.mean]), rtol=1e-5, atol=1e-6)
    assert full.mean.shape == (n, len(COMPONENTS), 3)


def test_brute_force_caster_matches_numpy_reference(cornell):
    # 4096 rays: above the batch size where an earlier (n, n_tri, 3) layout miscompiled on XLA:CPU.
    n = 4096
    o = np.asarray(jax.random.uniform(jax.random.key(0), (n, 3), jnp.float32, 50.0, 500.0))
    d = np.array(jax.random.normal(jax.random.key(1), (n, 3), jnp.float32))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    tri = np.asarray(cornell.triangles, np.float64)
    v0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    od, dd = o.astype(np.float64), d.astype(np.float64)
    p = np.cross(dd[:, None], e2[None])
    inv = 1.0 / np.sum(e1[None] * p, -1)
    s = od[:, None] - v0[None]
    u = np.sum(s * p, -1) * inv
    q = np.cross(s, e1[None])
    v = np.sum(dd[:, None] * q, -1) * inv
    t = np.sum(e2[None] * q, -1) * inv
    t = np.where((u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0), t, np.inf)
    ref_t, ref_tri = t.min(1), np.where(np.isfinite(t.min(1)), t.argmin(1), -1)
    hit = BruteForceCaster(cornell).closest_hit(jnp.asarray(o), jnp.asarray(d))
    got_t = np.asarray(hit.t)
    same = np.isclose(got_t, ref_t, rtol=1e-4) | (np.isinf(got_t) & np.isinf(ref_t))
    assert same.mean() > 0.999  # a ray grazing a shared edge may pick the neighbour in float32
    # Ties are real here (block bottoms lie on the floor): the picked triangle must be *a* nearest one.
    got_tri = np.asarray(hit.tri)
    picked_t = t[np.arange(n), np.maximum(got_tri, 0)]
    ok_tri = (got_tri == ref_tri) | np.isclose(picked_t, ref_t, rtol=1e-4)
    assert ok_tri.mean() > 0.999
    occ = BruteForceCaster(cornell).occluded(jnp.asarray(o), jnp.asarray(d), jnp.full(n, 100.0, jnp.float32))
    assert (np.asarray(occ) == (ref_t < 100.0)).mean() > 0.999


def test_save_render_roundtrip(cornell, tmp_path):
    cfg = RenderConfig(width=6, height=4, spp=8, max_depth=2, progress=False, paths_per_batch=_PPB)
    res = render(cornell, "front", cfg, key=0)
    exr, png = save_render(res, tmp_path / "img")
    layers = load_exr(exr)
    np.testing.assert_array_equal(layers[""], np.asarray(res.image("full")))
    for c in (c for c in COMPONENTS if c != "full"):
        np.testing.assert_array_equal(layers[c], np.asarray(res.image(c)))
        np.testing.assert_array_equal(layers[f"{c}_var"], np.asarray(res.variance(c)))
    from PIL import Image

    with Image.open(png) as im:
        assert im.size == (6, 4)


def test_bad_inputs(cornell):
    from probeplace._core import ConfigError

    with pytest.raises(ConfigError, match="spp"):
        RenderConfig(width=4, height=4, spp=0)
    with pytest.raises(KeyError, match="nope"):
        render(cornell, "nope", RenderConfig(width=4, height=4, spp=1, progress=False), key=0)
    with pytest.raises(TypeError, match="caster"):
        render(
            cornell, "front", RenderConfig(width=4, height=4, spp=1, progress=False), key=0, caster=object()
        )


def test_eqx_module_result_is_pytree(cornell):
    cfg = RenderConfig(width=4, height=4, spp=8, max_depth=2, progress=False, paths_per_batch=_PPB)
    res = render(cornell, "front", cfg, key=0)
    leaves = jax.tree.leaves(res)
    assert len(leaves) == 2 and isinstance(res, eqx.Module)


def test_glossy_direct_leaves_view_independent_radiance():
    # A glossy floor (roughness 0.2, dielectric) under a sun disk and a dim sky, seen from two directions:
    # along the sun's mirror direction (a strong GGX highlight) and from straight above. ``full`` is
    # several times brighter in the mirror view; what the floor reflects by its diffuse lobe,
    # direct − glossy_direct + diffuse_indirect, is (1 − F)·ρ/π × irradiance with Schlick's F ≈ 0.04 in
    # both views (wo·h ≥ 0.82 for the sun there), so the two agree within the sky's Fresnel term and the
    # noise, and lie just below the Lambert value ρ·E/π.
    r, theta = 0.08, 0.6
    sun_rgb = np.array([40.0, 20.0, 10.0])
    sun = make_sun((np.sin(theta), np.cos(theta), 0.0), sun_rgb, angular_radius=r)
    sky = np.array([0.02, 0.03, 0.05])
    v = np.array([[-100, 0, -100], [100, 0, -100], [100, 0, 100], [-100, 0, 100]], np.float64)
    f = np.array([[0, 2, 1], [0, 3, 2]])
    mats = make_materials(["floor"], base_color=np.full((1, 3), 0.5), roughness=np.array([0.2]))
    cam = make_camera((0.0, 1.0, 0.0), (0.0, 0.0, 0.01), 60.0, "down")
    scene = build_scene("glossy_floor", v, f, np.zeros(2, int), mats, views=(cam,), sun=sun, sky_radiance=sky)
    mirror = np.array([-np.sin(theta), np.cos(theta), 0.0])  # the sun's direction mirrored about +y
    above = np.array([0.0, 1.0, 0.0])
    n = 256
    origins = jnp.asarray(np.repeat(2.0 * np.stack([mirror, above]), n, axis=0), jnp.float32)
    dirs = jnp.asarray(np.repeat(-np.stack([mirror, above]), n, axis=0), jnp.float32)
    lambert = 0.5 * (sky + sun_rgb * np.sin(r) ** 2 * np.cos(theta))

    def split(rr):
        c = {k: np.asarray(rr.component(k), np.float64).reshape(2, n, 3) for k in rr.components}
        return c, c["direct"] - c["glossy_direct"] + c["diffuse_indirect"]

    rr = trace_rays(scene, origins, dirs, spp=64, key=3, max_depth=2)
    c, diffuse_lobe = split(rr)
    full = c["full"].mean(axis=1)
    assert np.all(full[0] > 3.0 * full[1]), full  # the scene has a highlight the test can see
    m = diffuse_lobe.mean(axis=1)
    se = diffuse_lobe.std(axis=1, ddof=1) / np.sqrt(n)
    np.testing.assert_allclose(m[0], m[1], rtol=0.02, atol=5 * float(se.max()))
    assert np.all(m <= lambert + 5 * se) and np.all(m >= 0.93 * lambert), (m, lambert)
    assert np.all(c["glossy_direct"] >= 0) and np.all(c["glossy_direct"] <= c["direct"] + 1e-6)
    # With the specular factor 0 there is no specular lobe: nothing is glossy.
    c0, _ = split(trace_rays(scene, origins, dirs, spp=8, key=4, max_depth=3, specular=0.0))
    assert not c0["glossy_direct"].any() and not c0["glossy_indirect"].any()


# ---- bounce schedules (PERF): live-lane compaction renders what the fused loop renders, on every caster.
# All schedules draw the same random numbers per (pixel, sample, bounce), so the oracle is the fused
# ``while_loop`` over every lane (the original design): images agree up to float round-off. (Here rather
# than in a file of their own: the compact render shares the Cornell kernel compiled above.)


def _render_schedule(scene, schedule, caster=None, **kw):
    cfg = RenderConfig(max_depth=6, rr_depth=3, progress=False, schedule=schedule, **kw)
    res = render(scene, "front", cfg, key=jax.random.key(3), caster=caster)
    return np.asarray(res.mean, np.float64), np.asarray(res.var_of_mean, np.float64)


@pytest.mark.isa
def test_compact_matches_fused(cornell):
    # 64 items × 16 samples in batches of _PPB = 512 paths: two batches per render; the compact one runs
    # the (64 items × 8 samples) kernel the Cornell renders above compile.
    kw = dict(width=8, height=8, spp=16, paths_per_batch=_PPB)
    m_c, v_c = _render_schedule(cornell, "compact", **kw)
    m_f, v_f = _render_schedule(cornell, "fused", **kw)
    assert m_c.max() > 0
    np.testing.assert_allclose(m_c, m_f, rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(v_c, v_f, rtol=1e-3, atol=1e-8)


@pytest.mark.isa
@pytest.mark.slow
def test_host_caster_compaction_matches_jitted(cornell):
    pytest.importorskip("embreex")
    from probeplace.geometry import make_caster

    kw = dict(width=16, height=16, spp=8)
    m_h, _ = _render_schedule(cornell, "compact", caster=make_caster(cornell, "embree"), **kw)
    m_j, _ = _render_schedule(cornell, "compact", **kw)
    # Embree and the brute-force caster differ in the last bits of t: a path may rarely take another
    # turn, so compare per pixel loosely and the image mean tightly
    close = np.isclose(m_h, m_j, rtol=1e-3, atol=1e-5)
    assert close.mean() > 0.98
    assert m_h[-1].mean() == pytest.approx(m_j[-1].mean(), rel=2e-2)


def test_bad_schedule():
    from probeplace._core import ConfigError

    with pytest.raises(ConfigError):
        RenderConfig(width=4, height=4, spp=1, schedule="nope")
