"""Exact ray casting: Embree, the JAX BVH and brute force agree; BVH build invariants; make_caster."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jaxtyping import TypeCheckError

from probeplace._core import ConfigError
from probeplace.geometry import (
    BruteForceCaster,
    BVHCaster,
    EmbreeCaster,
    make_caster,
)
from probeplace.geometry._bvh_build import build_bvh, thread_bvh
from probeplace.scene import load_scene
from tests.geometry.raycast_reference import assert_same_hits, random_rays

SCENES = ["cornell_box", "temple", "rooms", "courtyard"]
N_RAYS = 3000  # one ray count everywhere: each caster compiles once per scene


@pytest.fixture(scope="module", params=SCENES)
def scene_and_casters(request):
    scene = load_scene(request.param)
    casters = {"embree": EmbreeCaster(scene, threads=1), "bvh": BVHCaster(scene, lanes=512)}
    if scene.n_triangles <= BruteForceCaster.MAX_TRIANGLES:
        casters["brute"] = BruteForceCaster(scene, chunk=2048)
    return scene, casters


def test_backends_agree_on_closest_hit(scene_and_casters):
    scene, casters = scene_and_casters
    o, d = random_rays(scene, N_RAYS, seed=1)
    ref = casters["embree"].closest_hit(o, d, jnp.full(N_RAYS, jnp.inf, jnp.float32))
    assert 0.3 < float(ref.hit.mean()) <= 1.0  # the rays do meet the scene (a vacuous test otherwise)
    for name, caster in casters.items():
        if name != "embree":
            hit = caster.closest_hit(o, d, jnp.full(N_RAYS, jnp.inf, jnp.float32))
            assert_same_hits(scene, o, d, hit, ref, label=name)


@pytest.mark.parametrize("name", ["rooms"])
def test_fused_schedule_and_unsorted_rays_agree(name):
    scene = load_scene(name)
    o, d = random_rays(scene, 1500, seed=2)
    casters = {"embree": EmbreeCaster(scene, threads=1)}
    ref = casters["embree"].closest_hit(o, d)
    for caster in (
        BVHCaster(scene, schedule="fused", lanes=256),
        BVHCaster(scene, sort_rays=False, lanes=300),
    ):
        assert_same_hits(scene, o, d, caster.closest_hit(o, d), ref, label=caster.schedule)


def test_t_max_and_occluded(scene_and_casters):
    scene, casters = scene_and_casters
    o, d = random_rays(scene, N_RAYS, seed=3)
    full = np.asarray(casters["embree"].closest_hit(o, d).t)
    extent = float(np.linalg.norm(np.ptp(np.asarray(scene.vertices), axis=0)))
    t_max = np.random.default_rng(4).uniform(0.0, 0.6 * extent, o.shape[0]).astype(np.float32)
    # rays whose hit lies within float32 rounding of t_max could go either way: leave them out
    clear = np.abs(full - t_max) > 1e-5 * extent
    expect = full < t_max
    for name, caster in casters.items():
        occ = np.asarray(caster.occluded(o, d, jnp.asarray(t_max)))
        np.testing.assert_array_equal(occ[clear], expect[clear], err_msg=name)
        hit = caster.closest_hit(o, d, jnp.asarray(t_max))
        t = np.asarray(hit.t)
        assert np.all(t[np.isfinite(t)] < t_max[np.isfinite(t)]), name
        np.testing.assert_array_equal(np.isfinite(t)[clear], expect[clear], err_msg=name)


def test_dtype_in_equals_out(cornell):
    o, d = random_rays(cornell, 64, seed=5)
    cases = [(c, jnp.float32) for c in (BVHCaster(cornell, lanes=32), EmbreeCaster(cornell, threads=1))]
    cases += [(BruteForceCaster(cornell), jnp.float32), (BruteForceCaster(cornell), jnp.float64)]
    for caster, dtype in cases:
        hit = caster.closest_hit(o.astype(dtype), d.astype(dtype))
        assert hit.t.dtype == dtype and hit.bary.dtype == dtype and hit.geo_normal.dtype == dtype
        assert hit.tri.dtype == jnp.int32


def test_bvh_caster_is_jittable_without_retracing(cornell):
    caster = BVHCaster(cornell, lanes=64)
    o, d = random_rays(cornell, 100, seed=6)

    @jax.jit
    def first_t(c, o, d):
        return c.closest_hit(o, d).t

    a = first_t(caster, o, d)
    b = first_t(caster, o + 1.0, d)  # new values, same shapes: no retrace
    assert first_t._cache_size() == 1
    np.testing.assert_allclose(np.asarray(a), np.asarray(caster.closest_hit(o, d).t), rtol=0, atol=0)
    assert not np.array_equal(np.asarray(a), np.asarray(b))


def test_empty_and_bad_batches(cornell):
    caster = BVHCaster(cornell)
    empty = jnp.zeros((0, 3), jnp.float32)
    assert caster.closest_hit(empty, empty).t.shape == (0,)
    with pytest.raises((ValueError, TypeCheckError)):  # jaxtyping sees the shape mismatch first
        caster.closest_hit(jnp.zeros((4, 3)), jnp.zeros((5, 3)))
    with pytest.raises(ValueError, match="origins and directions"):
        EmbreeCaster(cornell)._run(
            np.zeros((4, 2), np.float32), np.zeros((4, 2), np.float32), 1.0, "INTERSECT"
        )


# --- BVH build invariants -------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["temple", "courtyard"])
def test_bvh_build_invariants(name):
    tri = np.asarray(load_scene(name).triangles, np.float64)
    bvh = build_bvh(tri)
    leaf = bvh.is_leaf
    # every triangle in exactly one leaf
    in_leaves = np.concatenate(
        [bvh.order[s : s + c] for s, c in zip(bvh.start[leaf], bvh.count[leaf], strict=True)]
    )
    np.testing.assert_array_equal(np.sort(in_leaves), np.arange(tri.shape[0]))
    assert bvh.count[leaf].max() == 1  # max_leaf = 1
    # leaf boxes hold their triangles; child boxes lie inside their parent
    for node in np.flatnonzero(leaf):
        ids = bvh.order[bvh.start[node] : bvh.start[node] + bvh.count[node]]
        assert np.all(tri[ids].min(axis=1) >= bvh.lo[node]) and np.all(tri[ids].max(axis=1) <= bvh.hi[node])
    inner = np.flatnonzero(~leaf)
    for child in (bvh.left[inner], bvh.right[inner]):
        assert np.all(bvh.lo[child] >= bvh.lo[inner]) and np.all(bvh.hi[child] <= bvh.hi[inner])
        np.testing.assert_array_equal(bvh.depth[child], bvh.depth[inner] + 1)


def test_threaded_layout_lists_each_triangle_once_per_octant():
    tri = np.asarray(load_scene("rooms").triangles, np.float64)
    th = thread_bvh(build_bvh(tri), tri)
    for octant in range(8):
        ids = th.tri[octant * th.n_items : (octant + 1) * th.n_items]
        np.testing.assert_array_equal(np.sort(ids[ids >= 0]), np.arange(tri.shape[0]))
    box = th.link >= 0
    # skip links only go forward (the walk terminates) and stay inside the octant's layout or the sentinel
    items = np.arange(th.link.shape[0])
    fwd = np.where(box, th.link, ~th.link)
    assert np.all(fwd[:-1] > items[:-1]) and fwd[-1] == th.sentinel
    assert np.all((fwd[:-1] // th.n_items == items[:-1] // th.n_items) | (fwd[:-1] == th.sentinel))
    assert np.all(np.isnan(th.a[:, th.sentinel]))


# --- make_caster ----------------------------------------------------------------------------------------


def test_make_caster_choices(cornell):
    assert isinstance(make_caster(cornell), EmbreeCaster)
    assert isinstance(make_caster(cornell, jittable=True), BruteForceCaster)
    assert isinstance(make_caster(load_scene("courtyard"), jittable=True), BVHCaster)
    assert isinstance(make_caster(cornell, "bvh", lanes=16), BVHCaster)
    assert make_caster(cornell, "embree", threads=1).threads == 1
    with pytest.raises(ConfigError, match="unknown ray-casting backend"):
        make_caster(cornell, "optix")
    with pytest.raises(ConfigError, match="cannot be jitted"):
        make_caster(cornell, "embree", jittable=True)
    with pytest.raises(ConfigError, match="schedule"):
        BVHCaster(cornell, schedule="wide")
