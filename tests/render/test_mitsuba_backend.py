"""The Mitsuba backend against the JAX path tracer (the oracle): the same estimator, so the same answer.

Two checks per case. *Common random numbers*: with the same key both backends draw the same numbers
(``_sampling.path_uniforms``), so every per-pixel / per-ray mean must match up to float32 round-off
(a rare path may branch differently at a threshold; see the module docstring of ``_mitsuba_backend``).
*Independent keys*: the means differ by noise only; block z-scores from both ``var_of_mean`` estimates
must look standard normal, component by component.

Each JAX batch kernel compiles for ~10–20 s on 2 cores (a new scene or ray source is a new kernel), so
the default run holds two: the glossy sunlit scene's image (camera rays, area light + sun + sky,
metal, smooth normals) and the Cornell box's probe rays; the Cornell reference image is ``slow``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import ConfigError, texel_directions
from probeplace.probes import BakeConfig, path_traced_radiance
from probeplace.render import COMPONENTS, RenderConfig, render, trace_rays
from probeplace.scene import build_scene, make_camera, make_materials, make_sun

mi = pytest.importorskip("mitsuba")

from probeplace.render._mitsuba_backend import load_mitsuba  # noqa: E402

try:
    load_mitsuba()
except ImportError as e:  # CI without libLLVM: the backend cannot run here
    pytest.skip(f"Mitsuba's LLVM variant cannot load: {e}", allow_module_level=True)

# 64 items × 8 samples per batch, as tests/render/test_render.py: the JAX kernels compile once.
_PPB = 512
_PROBES = np.array([[0.3, 0.5, 0.6], [0.7, 0.75, 0.5], [0.5, 0.8, 0.4], [0.5, 0.6, 0.8]])


def _crn_agree(a: np.ndarray, b: np.ndarray, frac: float = 0.98) -> None:
    """Same random numbers: nearly every entry equal up to float32 round-off accumulated over a path
    (1e-4 relative), and none off by more than a small share of the image's scale (a branch flip)."""
    tol = 1e-4 * (np.abs(a) + 1e-3)
    close = np.abs(a - b) <= tol
    assert close.mean() >= frac, (close.mean(), np.abs(a - b).max())
    assert np.abs(a - b).max() <= 0.05 * np.abs(a).max() + 1e-6


def _z_check(ma, va, mb, vb, axis_blocks) -> None:
    """z-scores of block means (``axis_blocks`` reshapes an item axis into (blocks, items per block)).

    Blocks average many items so both variance estimates are precise; entries where both backends
    have zero variance are deterministic (no light of that component there, or the emission a probe
    ray sees: every sample traces the same first ray) and must agree to round-off."""
    ma, va, mb, vb = (axis_blocks(np.asarray(x, np.float64)) for x in (ma, va, mb, vb))
    k = ma.shape[1]
    mean_a, mean_b = ma.mean(1), mb.mean(1)
    var = (va.sum(1) + vb.sum(1)) / k**2  # variance of a mean of k independent items
    det = var == 0
    # float32 round-off only (rtol: a mean of a few hundred float32 samples)
    np.testing.assert_allclose(mean_a[det], mean_b[det], rtol=1e-5, atol=1e-7)
    z = (mean_a - mean_b)[~det] / np.sqrt(var[~det])
    n = z.size
    assert n > 50, n
    # n ≈ 200–250 tests: P(any |z| > 5.5) < 1e-5 under H0
    assert np.abs(z).max() < 5.5, (np.abs(z).max(), n)
    # The entries are correlated (a block's RGB, full = the sum of the parts) and their variances are
    # estimates from heavy-tailed samples, so mean z² spreads wider than χ²(n)/n: 20 key pairs on the
    # glossy scene gave 0.74–1.59 (mean 1.10).
    assert 0.5 < np.mean(z**2) < 2.0, (np.mean(z**2), n)
    # A bias below the per-block noise shows in the mean over all blocks (18 tests per call).
    gvar = (va.sum((0, 1)) + vb.sum((0, 1))) / ma[:, :, 0, 0].size ** 2
    glob = (ma.mean((0, 1)) - mb.mean((0, 1)))[gvar > 0] / np.sqrt(gvar[gvar > 0])
    assert np.abs(glob).max() < 5.0, np.abs(glob).max()


def _blocks_image(b: int):
    def f(x):  # (comp, h, w, 3) -> (blocks, b², comp, 3)
        c, h, w, _ = x.shape
        x = x.reshape(c, h // b, b, w // b, b, 3).transpose(1, 3, 2, 4, 0, 5)
        return x.reshape((h // b) * (w // b), b * b, c, 3)

    return f


def _blocks_rays(k: int):
    def f(x):  # (n, comp, 3) -> (n / k, k, comp, 3)
        return x.reshape(-1, k, *x.shape[1:])

    return f


def _cfg(backend: str, **kw) -> RenderConfig:
    return RenderConfig(progress=False, paths_per_batch=_PPB, backend=backend, **kw)


@pytest.mark.slow
def test_cornell_reference_components_agree(cornell):
    # slow only for the JAX kernel's compile (~10–20 s on 2 cores); the glossy scene below covers the
    # same camera path, lights and components in the default run.
    kw = dict(width=32, height=32, spp=64, max_depth=6)
    jx = render(cornell, "front", _cfg("jax", **kw), key=jax.random.key(5))
    crn = render(cornell, "front", _cfg("mitsuba", **kw), key=jax.random.key(5))
    ind = render(cornell, "front", _cfg("mitsuba", **kw), key=jax.random.key(6))
    assert crn.components == jx.components == COMPONENTS
    assert crn.mean.dtype == jnp.float32 and crn.mean.shape == jx.mean.shape
    _crn_agree(np.asarray(jx.mean), np.asarray(crn.mean))
    _z_check(jx.mean, jx.var_of_mean, ind.mean, ind.var_of_mean, _blocks_image(4))


def _probe_rays(scene, res: int = 8):
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    pos = (lo + (hi - lo) * _PROBES).astype(np.float32)
    dirs = np.asarray(texel_directions(res), np.float32).reshape(-1, 3)
    origins = np.repeat(pos, len(dirs), axis=0)
    return jnp.asarray(origins), jnp.asarray(np.tile(dirs, (len(pos), 1)))


def test_cornell_bake_rays_agree(cornell):
    # Rays from probe centres, as the bake traces them (every sample the same first ray).
    o, d = _probe_rays(cornell)
    kw = dict(spp=16, max_depth=5)  # 256 rays × 16: one batch, the layout path_traced_radiance uses below
    jx = trace_rays(cornell, o, d, key=3, **kw)
    crn = trace_rays(cornell, o, d, key=3, backend="mitsuba", **kw)
    ind = trace_rays(cornell, o, d, key=4, backend="mitsuba", **kw)
    _crn_agree(np.asarray(jx.mean), np.asarray(crn.mean))
    _z_check(jx.mean, jx.var_of_mean, ind.mean, ind.var_of_mean, _blocks_rays(16))


@pytest.mark.parametrize("first_hit_lobes", ["all", "diffuse"])
def test_bake_radiance_function_agrees(cornell, first_hit_lobes):
    # path_traced_radiance's outputs (reflected, emitted[, every lobe]) with the same key: the same
    # numbers from both backends, whichever lobes the texel's surface reflects by.
    o, d = _probe_rays(cornell)
    fns = [
        path_traced_radiance(cornell, spp=16, max_depth=4, first_hit_lobes=first_hit_lobes, backend=be)
        for be in ("jax", "mitsuba")
    ]
    out_j, out_m = (fn(o, d, jax.random.key(9)) for fn in fns)
    assert len(out_j) == len(out_m) == (2 if first_hit_lobes == "all" else 3)
    for a, b in zip(out_j, out_m, strict=True):
        _crn_agree(np.asarray(a), np.asarray(b))


def _octahedron(subdivisions: int):
    """A unit sphere approximated by a subdivided octahedron (8 · 4ⁿ triangles, shared vertices)."""
    verts = [
        np.array(p, np.float64) for p in [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
    ]
    faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    for _ in range(subdivisions):
        cache: dict = {}

        def mid(i, j):
            key = (min(i, j), max(i, j))
            if key not in cache:
                p = verts[i] + verts[j]
                verts.append(p / np.linalg.norm(p))
                cache[key] = len(verts) - 1
            return cache[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
        faces = new
    return np.asarray(verts), np.asarray(faces)


def _glossy_sunlit():
    """A glossy white floor (dielectric, roughness 0.3) under a blob with smooth shading normals, green
    metal above and rough red plastic below, lit by a 3°-wide sun, a blue sky and a small area light:
    shadows, glossy interreflection, MIS of all three lights (sun and area light share the light
    samples) and interpolated normals (the Cornell box is flat).

    36 triangles, 2 of them emissive, the Cornell box's material and view names: the JAX batch kernel
    compiled for the Cornell box is reused (shapes and names are all that is static there)."""
    floor = np.array([[-20.0, 0.0, -20.0], [20.0, 0.0, -20.0], [20.0, 0.0, 20.0], [-20.0, 0.0, 20.0]])
    lamp = np.array([[-0.3, 2.5, -0.3], [0.3, 2.5, -0.3], [0.3, 2.5, 0.3], [-0.3, 2.5, 0.3]])
    sv, sf = _octahedron(1)  # 32 triangles
    verts = np.concatenate([floor, lamp, sv * 0.8 + np.array([0.0, 1.0, 0.0])])
    quad_up, quad_down = [[0, 2, 1], [0, 3, 2]], [[4, 5, 6], [4, 6, 7]]  # the lamp faces down
    faces = np.concatenate([quad_up, quad_down, sf + 8])
    lower = sv[sf].mean(axis=1)[:, 1] < 0
    tri_mat = np.r_[[0, 0, 3, 3], np.where(lower, 1, 2)]
    mats = make_materials(
        ["white", "red", "green", "light"],
        base_color=np.array([[0.8, 0.8, 0.8], [0.7, 0.1, 0.1], [0.3, 0.8, 0.35], [0.0, 0.0, 0.0]]),
        roughness=np.array([0.3, 0.7, 0.4, 1.0]),
        metallic=np.array([0.0, 0.0, 1.0, 0.0]),
        emission=np.array([[0.0] * 3, [0.0] * 3, [0.0] * 3, [20.0, 18.0, 15.0]]),
    )
    cam = make_camera((2.5, 2.5, 2.5), (0.0, 0.7, 0.0), 45.0, "front")
    sun = make_sun((0.4, 1.0, 0.3), (300.0, 280.0, 250.0), angular_radius=0.026)
    return build_scene(
        "glossy_sunlit", verts, faces, tri_mat, mats, views=(cam,), sun=sun, sky_radiance=(0.3, 0.4, 0.6)
    )


@pytest.mark.slow  # ~15 s; the Cornell bake-ray agreement test keeps the backend in the default run
def test_glossy_sunlit_scene_agrees(cornell):
    scene = _glossy_sunlit()
    assert scene.n_triangles == cornell.n_triangles  # see _glossy_sunlit: shares the compiled kernel
    kw = dict(width=16, height=16, spp=64, max_depth=5)
    jx = render(scene, "front", _cfg("jax", **kw), key=jax.random.key(1))
    crn = render(scene, "front", _cfg("mitsuba", **kw), key=jax.random.key(1))
    ind = render(scene, "front", _cfg("mitsuba", **kw), key=jax.random.key(2))
    gd = COMPONENTS.index("glossy_direct")
    assert float(jnp.max(jx.mean[gd])) > 0  # the scene exercises the specular lobe
    _crn_agree(np.asarray(jx.mean), np.asarray(crn.mean))
    _z_check(jx.mean, jx.var_of_mean, ind.mean, ind.var_of_mean, _blocks_image(4))


def _floor(sky, sun=None):
    """A large Lambertian floor (albedo 0.5) seen from above: every floor point sees the whole sky."""
    v = np.array([[-100, 0, -100], [100, 0, -100], [100, 0, 100], [-100, 0, 100]], np.float64)
    f = np.array([[0, 2, 1], [0, 3, 2]])
    mats = make_materials(["floor"], base_color=np.full((1, 3), 0.5))
    cam = make_camera((0.0, 1.0, 0.0), (0.0, 0.0, 0.01), 60.0, "down")
    return build_scene("floor", v, f, np.zeros(2, int), mats, views=(cam,), sun=sun, sky_radiance=sky)


@pytest.mark.parametrize("with_sun", [False, True])
def test_floor_under_sky_and_sun_closed_form(with_sun):
    # Closed form (tests/render/test_render.py's furnace): a Lambertian floor of albedo ρ under a
    # constant sky L and a sun disk of radiance S and angular radius r at zenith angle θ reflects
    # ρ (L + S sin²r cos θ). Sky only: no light sample at all (the sky is reached by BRDF sampling).
    theta, r = 0.5, 0.05
    sun = (
        make_sun((np.sin(theta), np.cos(theta), 0.0), (40.0, 20.0, 10.0), angular_radius=r)
        if with_sun
        else None
    )
    sky = np.array([0.2, 0.3, 0.5])
    cfg = _cfg("mitsuba", width=8, height=8, spp=512, max_depth=3, specular=0.0)
    res = render(_floor(tuple(sky), sun), "down", cfg, key=jax.random.key(1))
    expected = 0.5 * (
        sky + (np.array([40.0, 20.0, 10.0]) * np.sin(r) ** 2 * np.cos(theta) if with_sun else 0.0)
    )
    for comp, want in (("direct", expected), ("emission", np.zeros(3)), ("diffuse_indirect", np.zeros(3))):
        img = np.asarray(res.image(comp), np.float64)
        se = np.sqrt(np.asarray(res.variance(comp), np.float64).sum(axis=(0, 1))) / img[..., 0].size
        tol = 5.0 * se + 1e-5 * np.abs(want)  # 1e-5: float32 accumulation within one path
        assert np.all(np.abs(img.mean(axis=(0, 1)) - want) <= tol), (comp, img.mean(axis=(0, 1)), want, se)


def test_bake_records_backend(cornell):
    from probeplace.probes._bake import _settings

    fn = path_traced_radiance(cornell, spp=2, max_depth=3, backend="mitsuba")
    rec = _settings(cornell, fn, 8, BakeConfig(n_sub=1), jax.random.key(0))
    assert rec.backend == "mitsuba"
    assert type(rec).from_dict(rec.to_dict()).backend == "mitsuba"
    old = {k: v for k, v in rec.to_dict().items() if k != "backend"}  # a file from before the field
    assert type(rec).from_dict(old).backend == "jax"


def test_bad_backend_settings_are_refused(cornell):
    with pytest.raises(ConfigError, match="'cuda'"):
        RenderConfig(width=4, height=4, spp=1, backend="cuda")
    with pytest.raises(ConfigError, match="backend"):
        path_traced_radiance(cornell, backend="optix")
    from probeplace.render import default_caster

    with pytest.raises(ConfigError, match="caster"):
        path_traced_radiance(cornell, backend="mitsuba", caster=default_caster(cornell))
    o, d = _probe_rays(cornell, res=2)
    with pytest.raises(ConfigError, match="caster"):
        trace_rays(cornell, o, d, spp=1, key=0, backend="mitsuba", caster=default_caster(cornell))


def test_missing_llvm_variant_is_a_clear_error(monkeypatch):
    import probeplace.render._mitsuba_backend as mb

    monkeypatch.setattr(mi, "variant", lambda: "scalar_rgb")
    monkeypatch.setattr(mi, "variants", lambda: ["scalar_rgb"])
    with pytest.raises(ImportError, match="llvm_ad_rgb"):
        mb.load_mitsuba()


def test_auto_backend_picks_mitsuba_on_a_cpu_and_jax_without_it(cornell, monkeypatch):
    """``"auto"``: Mitsuba where its LLVM variant loads (this module runs only there) on a CPU, JAX when it
    cannot load or when JAX runs on an accelerator; the settings records hold the resolved name."""
    import probeplace.render._mitsuba_backend as mb
    import probeplace.render._render as rr
    from probeplace.evaluate import EvalConfig
    from probeplace.probes._bake import _settings
    from probeplace.render import BACKENDS, default_caster, resolve_backend

    expected = "mitsuba" if jax.default_backend() == "cpu" else "jax"
    assert resolve_backend("auto") == expected
    assert RenderConfig(width=4, height=4, spp=1, backend="auto").backend == expected
    assert EvalConfig(width=4, height=4, spp=1, backend="auto").backend == expected
    # a caster is a JAX-only speed-up: with "auto" it is dropped when Mitsuba is picked, not refused
    fn = path_traced_radiance(cornell, spp=2, max_depth=3, backend="auto", caster=default_caster(cornell))
    assert fn.backend == expected and (fn.caster is None) == (expected == "mitsuba")
    assert _settings(cornell, fn, 8, BakeConfig(n_sub=1), jax.random.key(0)).backend == expected
    for name in BACKENDS:  # a named backend is never replaced
        assert resolve_backend(name) == name
    with pytest.raises(ConfigError, match=r"EvalConfig.backend must be one of .*'auto'.*got 'fast'"):
        EvalConfig(width=4, height=4, spp=1, backend="fast")

    def no_llvm():
        raise ImportError("no LLVM here")

    rr._auto_backend.cache_clear()
    monkeypatch.setattr(mb, "load_mitsuba", no_llvm)
    monkeypatch.setattr(jax, "default_backend", lambda: "cpu")
    try:
        assert resolve_backend("auto") == "jax"
    finally:
        rr._auto_backend.cache_clear()
