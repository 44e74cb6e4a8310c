"""The wavefront engine (``probes/tracer/_wavefront.py``) against the per-ray engine on the same rays.

Oracle: the per-ray engine (``trace_ray``), which runs the same per-step functions in nested loops. Every
integer field of ``TraceResult`` (status, probe, texel, march steps, probes tried, fallback count) must be
equal. ``t`` is compared to within a few float32 ulps at the scene's scale, not bit for bit: the engines
are different XLA programs, and XLA's CPU backend contracts multiply–adds into FMAs per fusion, so the
same float32 expression can round differently. The per-ray engine differs from itself this way between
batch sizes (Cornell box, 64² maps, the first 1000 of 2000 shading rays traced alone: 15% of t differ,
by up to 8 ulps); between the engines we measured up to ≈ 4·eps·(scene diagonal).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import ConfigError
from probeplace.geometry import BruteForceCaster, make_caster
from probeplace.probes import (
    BakeConfig,
    TraceConfig,
    TraceStatus,
    bake_probes,
    make_tracer,
    trace_light_field,
)
from probeplace.probes.tracer._index import voxel_index
from probeplace.scene import load_scene
from tests.helpers import grid_probe_set, shared_scene_path

RES = 32  # geometry maps: small, so the bakes and traces stay quick on two CPU cores
INT_FIELDS = ("status", "probe", "texel", "steps", "probes_tried", "fallback")


def _const(o, d, k):
    n = o.shape[0]
    return jnp.full((n, 3), 0.5, o.dtype), jnp.zeros((n, 3), o.dtype)


def _bake_grid(scene, dims, caster, geometry_res=None):
    """Probes at the centres of a ``dims`` grid of cells over the scene bounds, baked with constant
    radiance."""
    probes = grid_probe_set(scene, dims)
    cfg = BakeConfig(
        radiance_res=RES, geometry_res=geometry_res, irradiance_res=4, moments_res=4, n_sub=1, progress=False
    )
    return bake_probes(scene, probes, caster=caster, radiance_fn=_const, key=jax.random.key(0), config=cfg)


def _free_rays(scene, caster, n, seed):
    """Rays from free space: origins uniform in the scene box among the points the first view's camera
    sees unobstructed (the segment from it is free, so the point is not inside geometry), directions
    uniform on the sphere; every fourth ray gets a finite ``t_max``."""
    rng = np.random.default_rng(seed)
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    cam = np.asarray(scene.views[0].position, np.float64)
    o = np.zeros((0, 3))
    for _ in range(8):  # Sponza's camera sees about a tenth of its box
        q = rng.uniform(lo, hi, (4 * n, 3))
        dist = np.linalg.norm(q - cam, axis=1)
        v = (q - cam) / dist[:, None]
        h = caster.closest_hit(
            jnp.asarray(np.repeat(cam[None], len(q), 0), jnp.float32), jnp.asarray(v, jnp.float32)
        )
        o = np.concatenate([o, q[np.asarray(h.t, np.float64) > 1.001 * dist]])[:n]
        if len(o) == n:
            break
    assert len(o) == n, "too few free points"
    d = rng.normal(size=o.shape)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t_max = np.where(np.arange(n) % 4 == 0, rng.uniform(0.05, 0.5, n) * np.linalg.norm(hi - lo), np.inf)
    return jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32), jnp.asarray(t_max, jnp.float32)


def _t_atol(scene) -> float:
    """Tolerance on t: 32·eps·(scene diagonal), 8× the largest difference measured between the engines
    (module docstring)."""
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    return 32 * float(np.finfo(np.float32).eps) * float(np.linalg.norm(hi - lo))


def _assert_same(a, b, atol):
    for f in INT_FIELDS:
        np.testing.assert_array_equal(np.asarray(getattr(a, f)), np.asarray(getattr(b, f)), err_msg=f)
    ta, tb = np.asarray(a.t, np.float64), np.asarray(b.t, np.float64)
    np.testing.assert_array_equal(np.isfinite(ta), np.isfinite(tb))
    fin = np.isfinite(ta)
    np.testing.assert_allclose(tb[fin], ta[fin], rtol=0, atol=atol)


def _assert_covers(ref):
    """The rays exercise every outcome: hits, misses or unresolved rays, and fallback probes."""
    st = np.asarray(ref.status)
    assert (st == TraceStatus.HIT).sum() > 10
    assert (st == TraceStatus.UNRESOLVED).sum() > 10
    assert (np.asarray(ref.fallback) > 0).sum() > 10
    return st


# ------------------------------------------------------------------------------------- Cornell box
@pytest.fixture(scope="module")
def cornell_case(cornell):
    caster = BruteForceCaster(cornell)
    lf = _bake_grid(cornell, (4, 4, 4), caster)
    o, d, t_max = _free_rays(cornell, caster, 3000, seed=0)
    ref = trace_light_field(make_tracer(lf, cornell.bounds), o, d, t_max)
    return cornell, lf, (o, d, t_max), ref


def _wavefront(lf, scene, rays, **kw):
    cfg = TraceConfig(engine="wavefront", **kw)
    return trace_light_field(make_tracer(lf, scene.bounds, config=cfg), *rays)


@pytest.mark.isa
def test_wavefront_matches_per_ray_cornell(cornell_case):
    scene, lf, rays, ref = cornell_case
    st = _assert_covers(ref)
    assert (st == TraceStatus.MISS).sum() > 10  # the box's open front
    out = _wavefront(lf, scene, rays, wavefront_lanes=256, wavefront_steps=4)
    _assert_same(ref, out, _t_atol(scene))
    assert out.t.dtype == jnp.float32


def test_wavefront_matches_per_ray_at_the_papers_resolution(cornell):
    """The two engines agree at Wang's 512² geometry maps (issue 33: the compact maps — one-byte bound
    codes, bfloat16 normals, distance-only surfels — are read by both through the same accessors, so only
    how the engines schedule the steps differs): a 2×2×2 grid on the Cornell box, 600 rays."""
    caster = BruteForceCaster(cornell)
    lf = _bake_grid(cornell, (2, 2, 2), caster, geometry_res=512)
    rays = _free_rays(cornell, caster, 600, seed=1)
    tr = make_tracer(lf, cornell.bounds)
    assert tr.res == 512 and tr.march_res == 1024
    ref = trace_light_field(tr, *rays)
    st = np.asarray(ref.status)
    assert (st == TraceStatus.HIT).sum() > 100 and (
        st == TraceStatus.MISS
    ).sum() > 10  # hits and the open front
    _assert_same(ref, _wavefront(lf, cornell, rays, wavefront_lanes=256, wavefront_steps=8), _t_atol(cornell))


@pytest.mark.slow  # 22 s on 2 cores (CI time); the default run holds the tracer identity at one batch size
def test_batch_size_and_refill_do_not_change_results(cornell_case):
    """Fewer lanes (so refill and the tail compaction run far more often) and another refill period give
    the same results; the integer fields are compared exactly, t as in the module docstring."""
    scene, lf, rays, _ = cornell_case
    a = _wavefront(lf, scene, rays, wavefront_lanes=256, wavefront_steps=4)
    b = _wavefront(lf, scene, rays, wavefront_lanes=48, wavefront_steps=3)
    _assert_same(a, b, _t_atol(scene))


@pytest.mark.slow
def test_wavefront_matches_per_ray_voxel_index(cornell_case):
    """Wang's voxel index (the other probe-selection branch) and a small probe budget, so that many rays
    end unresolved or need the fallback search."""
    scene, lf, rays, _ = cornell_case
    index = voxel_index(lf, scene.bounds, k=4, max_voxels_per_axis=8)
    cfg = dict(max_probes=4, fallback_probes=2, hierarchy="two_level")
    ref = trace_light_field(make_tracer(lf, scene.bounds, index=index, config=TraceConfig(**cfg)), *rays)
    _assert_covers(ref)
    wf = TraceConfig(engine="wavefront", wavefront_lanes=512, **cfg)
    out = trace_light_field(make_tracer(lf, scene.bounds, index=index, config=wf), *rays)
    _assert_same(ref, out, _t_atol(scene))


def test_engine_config_errors():
    with pytest.raises(ConfigError, match="engine"):
        TraceConfig(engine="megakernel")
    with pytest.raises(ConfigError, match="wavefront_lanes"):
        TraceConfig(wavefront_lanes=0)
    with pytest.raises(ConfigError, match="wavefront_steps"):
        TraceConfig(wavefront_steps=True)


# ------------------------------------------------------------------------------------------- Sponza
@pytest.fixture(scope="module")
def sponza():
    return load_scene(shared_scene_path("crytek_sponza.glb"))


@pytest.mark.slow  # ~45 s on 2 cores (CI time); the default run holds the identity on Cornell, and
# benchmarks/tracer.py reports the rays that differ on Sponza (wavefront_rays_differing) when it times them
def test_wavefront_matches_per_ray_sponza(sponza):
    """Sponza, 8×4×4 probes (Wang 2019's equal-quality grid; many probes inside the walls are unusable)."""
    caster = make_caster(sponza)
    lf = _bake_grid(sponza, (8, 4, 4), caster)
    rays = _free_rays(sponza, caster, 1500, seed=1)
    ref = trace_light_field(make_tracer(lf, sponza.bounds), *rays)
    _assert_covers(ref)
    out = _wavefront(lf, sponza, rays, wavefront_lanes=256)
    _assert_same(ref, out, _t_atol(sponza))
