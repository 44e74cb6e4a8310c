"""Property-based tests (issue 9, hypothesis): ray casters on random meshes and rays, the light-field
tracer on random rays (and, under ``slow``, random probe sets), and random config values.

Oracles: a float64 brute-force Möller–Trumbore reference with a *lenient* (edges widened) and a *strict*
(edges narrowed) triangle test. A correct caster's distance lies between the lenient and the strict
nearest distance, so a ray grazing an edge may hit or miss (a tie) but nothing else may differ. Shapes
are fixed per test (triangle and ray counts), so each caster compiles once however many examples run.
"""

from __future__ import annotations

import dataclasses
import math

import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from probeplace._core import ConfigError
from probeplace.geometry import BruteForceCaster, BVHCaster, EmbreeCaster
from probeplace.scene import build_scene, make_materials

from .conftest import SLOW, SLOW_COMPILING, cornell_probes

N_TRI, N_RAYS = 12, 64
MATS = make_materials(["m"], np.array([[0.5, 0.5, 0.5]]))
# Relative float32 slack of two different intersection formulas: a few hundred ulp of the scene extent.
RTOL = 2e-5
EDGE_EPS = 1e-4  # barycentric widening of the lenient / narrowing of the strict reference test


def _mt_all(tris, o, d, eps):
    """float64 Möller–Trumbore of every ray against every triangle (n_rays, n_tri); inf on a miss."""
    e1 = tris[None, :, 1] - tris[None, :, 0]
    e2 = tris[None, :, 2] - tris[None, :, 0]
    dd = d[:, None, :]
    p = np.cross(dd, e2)
    det = np.sum(e1 * p, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = o[:, None, :] - tris[None, :, 0]
        u = np.sum(s * p, axis=-1) * inv
        q = np.cross(s, e1)
        v = np.sum(dd * q, axis=-1) * inv
        t = np.sum(e2 * q, axis=-1) * inv
    ok = (np.abs(det) > 1e-300) & (u >= -eps) & (v >= -eps) & (u + v <= 1 + eps) & (t > 0)
    return np.where(ok, t, np.inf)


def _assert_between_references(scene, o, d, hit, label):
    tris = np.asarray(scene.vertices, np.float64)[np.asarray(scene.faces)]
    o64, d64 = np.asarray(o, np.float64), np.asarray(d, np.float64)
    t_lo = _mt_all(tris, o64, d64, EDGE_EPS).min(axis=1)
    t_hi = _mt_all(tris, o64, d64, -EDGE_EPS).min(axis=1)
    t = np.asarray(hit.t, np.float64)
    tri = np.asarray(hit.tri)
    assert not np.isnan(t).any(), f"{label}: NaN distance"
    assert np.array_equal(np.isfinite(t), tri >= 0), f"{label}: t finite exactly where a triangle is hit"
    extent = float(np.linalg.norm(np.ptp(tris.reshape(-1, 3), axis=0)))
    tol = RTOL * (extent + np.linalg.norm(o64, axis=1))
    with np.errstate(invalid="ignore"):
        ok = (t >= t_lo - tol) & ((t <= t_hi + tol) | np.isinf(t_hi))
    # A ray starting on a surface (to float32 precision) may report that surface at t ≈ 0: callers offset
    # secondary rays themselves (documented in geometry._raycast), so such a self-hit is not an error.
    ok |= (t >= 0) & (t <= tol)  # Embree reports such a self-hit as t = -0.0
    # From exactly a vertex, a grazing ray's float32 self-hit can reach further (Möller–Trumbore's error
    # grows as 1/|det|); allow 1e-3 of the extent there (the error of a ray offset the caller skipped).
    on_vertex = np.min(np.linalg.norm(o64[:, None] - tris.reshape(1, -1, 3), axis=-1), axis=1) == 0
    ok |= on_vertex & (t >= 0) & (t <= 1e-3 * extent)
    bad = np.flatnonzero(~ok)
    assert bad.size == 0, f"{label}: rays {bad[:5]} t={t[bad[:5]]} outside [{t_lo[bad[:5]]}, {t_hi[bad[:5]]}]"
    h = tri >= 0
    for name in ("geo_normal", "shading_normal"):
        assert np.isfinite(np.asarray(getattr(hit, name))[h]).all(), f"{label}: non-finite {name}"


def _soup(seed: int, scale: float):
    """N_TRI random triangles in a cube of side ``scale`` (non-degenerate with probability 1)."""
    rng = np.random.default_rng(seed)
    v = rng.uniform(0.0, scale, (N_TRI * 3, 3))
    f = np.arange(N_TRI * 3).reshape(N_TRI, 3)
    return build_scene("soup", v, f, np.zeros(N_TRI, int), MATS)


def _rays(scene, seed: int):
    """Origins around the mesh's box, directions aimed at random points inside it (so most rays hit)."""
    rng = np.random.default_rng(seed + 1)
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    ext = hi - lo
    o = rng.uniform(lo - 0.5 * ext, hi + 0.5 * ext, (N_RAYS, 3))
    target = rng.uniform(lo, hi, (N_RAYS, 3))
    # a quarter of the rays start on a triangle's vertex (a hit at t = 0 must not be reported)
    v = np.asarray(scene.vertices, np.float64)
    o[: N_RAYS // 4] = v[rng.integers(0, len(v), N_RAYS // 4)]
    d = target - o
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-30)
    d[np.linalg.norm(d, axis=1) < 0.5] = [0.0, 1.0, 0.0]
    return jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32)


def _check_brute_and_embree(seed: int, scale: float):
    scene = _soup(seed, scale)
    if scene.n_triangles != N_TRI:  # a (measure-zero) degenerate draw was dropped: another shape
        return
    o, d = _rays(scene, seed)
    for name, caster in (("brute", BruteForceCaster(scene)), ("embree", EmbreeCaster(scene, threads=1))):
        _assert_between_references(scene, o, d, caster.closest_hit(o, d), name)


@given(seed=st.integers(0, 2**31 - 1), scale=st.sampled_from([1e-3, 1.0, 1e3]))
def test_brute_force_and_embree_match_the_float64_reference(seed, scale):
    _check_brute_and_embree(seed, scale)


@pytest.mark.slow
@SLOW
@given(seed=st.integers(0, 2**31 - 1), scale=st.sampled_from([1e-3, 1.0, 1e3, 1e6]))
def test_brute_force_and_embree_match_the_float64_reference_slow(seed, scale):
    _check_brute_and_embree(seed, scale)


@pytest.fixture(scope="module")
def cornell_bvh_base(cornell):
    return cornell


@given(
    seed=st.integers(0, 2**31 - 1),
    scale=st.floats(1e-3, 1e3),
    shift=st.tuples(*[st.floats(-1e3, 1e3)] * 3),
)
@pytest.mark.isa
def test_bvh_matches_the_float64_reference_on_moved_cornell(cornell_bvh_base, seed, scale, shift):
    """The BVH on the Cornell box under a random uniform scale and translation: SAH splits are invariant
    under both, so the BVH keeps its layout and compiles once; rays and vertex values are new per example."""
    c = cornell_bvh_base
    v = np.asarray(c.vertices, np.float64) * scale + np.asarray(shift)
    scene = build_scene("moved", v, np.asarray(c.faces), np.asarray(c.tri_material), c.materials)
    o, d = _rays(scene, seed)
    _assert_between_references(scene, o, d, _bvh(scene).closest_hit(o, d), "bvh")


def _bvh(scene):
    """BVHCaster with 64 lanes (``build_seconds`` is a leaf, so new instances share one compilation)."""
    return BVHCaster(scene, lanes=64)


@pytest.mark.slow
@SLOW_COMPILING
@given(seed=st.integers(0, 2**31 - 1), scale=st.sampled_from([1e-3, 1.0, 1e3]))
def test_bvh_matches_the_float64_reference_on_random_meshes_slow(seed, scale):
    """Random soups: each BVH layout compiles anew, hence slow."""
    scene = _soup(seed, scale)
    o, d = _rays(scene, seed)
    _assert_between_references(scene, o, d, _bvh(scene).closest_hit(o, d), "bvh")


# ------------------------------------------------------------------------------------------- tracer
def _assert_trace_ok(tr, res, o, label=""):
    status = np.asarray(res.status)
    t = np.asarray(res.t)
    assert set(np.unique(status)) <= {0, 1, 2}, label
    assert not np.isnan(t).any(), f"{label}: NaN t"
    assert np.isinf(t[status == 0]).all(), f"{label}: a miss has a finite t"
    assert np.isfinite(t[status != 0]).all(), f"{label}: a hit / unresolved ray has no finite t"
    assert (t[status != 0] >= 0).all(), label
    assert (np.asarray(res.steps) >= 0).all() and (np.asarray(res.probes_tried) <= tr.config.max_probes).all()
    hit_p = np.asarray(res.probe)[status == 1]
    assert ((hit_p >= 0) & (hit_p < tr.pos_world.shape[0])).all(), label


_unit = st.tuples(*[st.floats(-1.0, 1.0, allow_nan=False)] * 3).filter(lambda v: 1e-3 < np.linalg.norm(v))


@given(
    origins=st.lists(st.tuples(*[st.floats(0.0, 1.0)] * 3), min_size=N_RAYS, max_size=N_RAYS),
    directions=st.lists(_unit, min_size=N_RAYS, max_size=N_RAYS),
    on_probe=st.integers(0, 7),
)
def test_tracer_terminates_with_finite_output(cornell, cornell_baked, origins, directions, on_probe):
    """Random rays in the Cornell box (origins anywhere in its box, one batch starting exactly at a probe,
    which includes the coincident pair and the probe on the floor): status is miss/hit/unresolved, t is
    inf for misses and finite otherwise."""
    _, tr = cornell_baked
    lo, hi = (np.asarray(b, np.float64) for b in cornell.bounds)
    o = lo + np.asarray(origins) * (hi - lo)
    o[: N_RAYS // 8] = cornell_probes(cornell)[on_probe]
    d = np.asarray(directions, np.float64)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    from probeplace.probes import trace_light_field

    res = trace_light_field(tr, jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32))
    _assert_trace_ok(tr, res, o)


@pytest.mark.slow
@SLOW_COMPILING
@given(frac=st.lists(st.tuples(*[st.floats(0.0, 1.0)] * 3), min_size=6, max_size=6), dup=st.booleans())
def test_tracer_on_random_probe_sets_slow(cornell, frac, dup):
    """Random probe sets (including coincident probes and probes on the box's walls) rebaked per example."""
    from probeplace.probes import make_tracer, trace_light_field

    from .catalogue import bake

    lo, hi = (np.asarray(b, np.float64) for b in cornell.bounds)
    pos = lo + np.asarray(frac) * (hi - lo)
    if dup:
        pos[1] = pos[0]
    lf = bake(cornell, pos, radiance_res=16)
    try:
        tr = make_tracer(lf, cornell.bounds)
    except ConfigError as e:  # every probe inside a block: refused with a message, not garbage
        assert "no usable probe" in str(e)
        return
    rng = np.random.default_rng(0)
    o = rng.uniform(lo, hi, (N_RAYS, 3))
    d = rng.normal(size=(N_RAYS, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    res = trace_light_field(tr, jnp.asarray(o, jnp.float32), jnp.asarray(d, jnp.float32))
    _assert_trace_ok(tr, res, o)


# ------------------------------------------------------------------------------------------- configs
_floats = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, -1.0, 1e-300]))
_ints = st.integers(-(2**40), 2**40)


def _strategy_for(annotation: str):
    if annotation == "int":
        return _ints
    if annotation == "float":
        return _floats
    if annotation == "int | None":
        return st.one_of(st.none(), _ints)
    if annotation == "bool":
        return st.booleans()
    return None


def _config_classes():
    from probeplace.placement import FitnessConfig
    from probeplace.probes import BakeConfig, TraceConfig
    from probeplace.render import RenderConfig

    return {"RenderConfig": RenderConfig, "BakeConfig": BakeConfig, "TraceConfig": TraceConfig,
            "FitnessConfig": FitnessConfig}  # fmt: skip


def _fields(cls):
    if dataclasses.is_dataclass(cls):
        return [(f.name, str(f.type)) for f in dataclasses.fields(cls)]
    return [(k, str(v)) for k, v in cls.__annotations__.items()]  # eqx.Module


@pytest.mark.parametrize("name", ["RenderConfig", "BakeConfig", "TraceConfig", "FitnessConfig"])
@given(data=st.data())
def test_random_config_values_are_refused_or_valid(name, data):
    """Any value of the annotated type is either refused with a ConfigError naming a field, or accepted —
    and an accepted config holds no NaN and no negative count."""
    cls = _config_classes()[name]
    kwargs = {}
    for field, ann in _fields(cls):
        strat = _strategy_for(ann)
        if strat is not None and data.draw(st.booleans(), label=f"set {field}"):
            kwargs[field] = data.draw(strat, label=field)
    if name == "RenderConfig":
        kwargs = {"width": 4, "height": 4, "spp": 1, **kwargs}
    if "hierarchy" in dict(_fields(cls)):
        kwargs["hierarchy"] = data.draw(st.sampled_from(["hiz", "flat", "two_level", "octree"]))
    try:
        cfg = cls(**kwargs)
    except ConfigError as e:
        assert any(f in str(e) for f, _ in _fields(cls)), str(e)
        return
    for field, ann in _fields(cls):
        v = getattr(cfg, field)
        if ann == "float":
            assert not math.isnan(v), f"{name}.{field}=nan accepted"
        if ann in ("int", "int | None") and v is not None and field not in ("hiz_skip_top",):
            assert v >= 1 or field in ("w1", "w2"), f"{name}.{field}={v} accepted"


@pytest.mark.isa
def test_chunked_tracing_matches_unchunked(cornell, cornell_baked):
    """``trace_light_field(..., chunk=k)`` (bounded memory, benchmarks/memory.py) gives the same answers as
    the one-batch trace, including a last partial chunk (N_RAYS = 64 rays, chunk 24). N_RAYS rays: the
    one-batch trace is the one test_tracer_terminates_with_finite_output compiles."""
    from probeplace.probes import trace_light_field

    _, tr = cornell_baked
    lo, hi = (np.asarray(b, np.float64) for b in cornell.bounds)
    rng = np.random.default_rng(3)
    o = jnp.asarray(lo + rng.uniform(0.05, 0.95, (N_RAYS, 3)) * (hi - lo), jnp.float32)
    d = rng.normal(size=(N_RAYS, 3))
    d = jnp.asarray(d / np.linalg.norm(d, axis=1, keepdims=True), jnp.float32)
    a = trace_light_field(tr, o, d)
    assert N_RAYS % 24 != 0
    b = trace_light_field(tr, o, d, chunk=24)
    np.testing.assert_array_equal(np.asarray(a.status), np.asarray(b.status))
    np.testing.assert_array_equal(np.asarray(a.probe), np.asarray(b.probe))
    # same per-ray arithmetic; only XLA's fusion may differ: a few float32 ulp of the scene size
    np.testing.assert_allclose(np.asarray(a.t), np.asarray(b.t), rtol=1e-5, atol=1e-5 * float(hi.max()))
