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
    complete_hit,
    make_caster,
)
from probeplace.geometry._bvh_build import build_bvh, thread_bvh
from probeplace.scene import build_scene, load_scene, make_materials
from tests.geometry.raycast_reference import (
    assert_same_hits,
    compare_hits,
    random_rays,
    tie_or_same,
    verified_ties,
)

SCENES = ["cornell_box", "temple", "rooms", "courtyard"]
N_RAYS = 3000  # one ray count everywhere: each caster compiles once per scene


@pytest.fixture(scope="module", params=SCENES)
def scene_and_casters(request):
    scene = load_scene(request.param)
    casters = {"embree": EmbreeCaster(scene, threads=1), "bvh": BVHCaster(scene, lanes=512)}
    if scene.n_triangles <= BruteForceCaster.MAX_TRIANGLES:
        casters["brute"] = BruteForceCaster(scene, chunk=2048)
    return scene, casters


@pytest.mark.isa
def test_backends_agree_on_closest_hit(scene_and_casters):
    scene, casters = scene_and_casters
    o, d = random_rays(scene, N_RAYS, seed=1)
    ref = casters["embree"].closest_hit(o, d, jnp.full(N_RAYS, jnp.inf, jnp.float32))
    assert 0.3 < float(ref.hit.mean()) <= 1.0  # the rays do meet the scene (a vacuous test otherwise)
    for name, caster in casters.items():
        if name != "embree":
            hit = caster.closest_hit(o, d, jnp.full(N_RAYS, jnp.inf, jnp.float32))
            assert_same_hits(scene, o, d, hit, ref, label=name)


@pytest.mark.isa
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


def _t_and_normal_plus(hit, shift):
    return hit.t + shift, hit.geo_normal, hit.shading_normal


@pytest.mark.isa
def test_closest_hit_map_and_the_face_normal_table(cornell):
    """``closest_hit_map(fn, …)`` is ``fn`` of ``closest_hit`` (one program for Embree, the caller's for a
    JAX caster), and ``complete_hit`` with the scene's ``face_normals`` table (Embree's) gives the normals
    it computes from the corners: the same float32 cross product and normalisation, in another program
    (an FMA contracted or not: a few ulps of a unit vector, within 1e-6)."""
    from probeplace.geometry._raycast import face_normals

    o, d = random_rays(cornell, 500, seed=7)
    shift = jnp.float32(0.5)
    for caster in (EmbreeCaster(cornell, threads=1), BVHCaster(cornell, lanes=64)):
        hit = caster.closest_hit(o, d)
        got = caster.closest_hit_map(_t_and_normal_plus, o, d, shift)
        for a, b in zip(got, _t_and_normal_plus(hit, shift), strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    hit = BVHCaster(cornell, lanes=64).closest_hit(o, d)
    assert 0.3 < float(hit.hit.mean()) < 1.0
    table = face_normals(cornell.vertices[cornell.faces])
    with_table = complete_hit(cornell, hit.t, hit.tri, hit.bary, table)
    without = complete_hit(cornell, hit.t, hit.tri, hit.bary)
    for field in ("t", "tri", "bary", "shading_normal", "material"):
        np.testing.assert_array_equal(
            np.asarray(getattr(with_table, field)), np.asarray(getattr(without, field))
        )
    np.testing.assert_allclose(np.asarray(with_table.geo_normal), np.asarray(without.geo_normal), atol=1e-6)


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


# --- ties: overlapping coplanar triangles -------------------------------------------------------------
# A and B lie in the plane z = 0 and overlap; C is parallel to them, 0.5 below A. Every coordinate is
# dyadic (exact in float32). A ray through the overlap crosses A and B at the same distance: which one a
# caster reports follows its traversal order (for Embree, the instruction set it picks at run time), so
# the checks must accept either, whatever the triangle order in the scene.
A, B, C = 0, 1, 2
TIE_TRIANGLES = np.array(
    [
        [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]],  # A
        [[0.5, 0.5, 0.0], [2.5, 0.5, 0.0], [0.5, 2.5, 0.0]],  # B: overlaps A in x, y >= 0.5, x + y <= 2
        [[0.0, 0.0, -0.5], [2.0, 0.0, -0.5], [0.0, 2.0, -0.5]],  # C: below A
    ],
    np.float32,
)
ORDERS = [(0, 1, 2), (1, 0, 2), (2, 1, 0)]  # scene triangle i is TIE_TRIANGLES[order[i]]


def _tie_scene(order):
    tris = TIE_TRIANGLES[list(order)]
    mats = make_materials(["a", "b", "c"], np.eye(3))  # a material per triangle: a tie may differ in it
    scene = build_scene("ties", tris.reshape(-1, 3), np.arange(9).reshape(3, 3), np.asarray(order), mats)
    np.testing.assert_array_equal(np.asarray(scene.triangles), tris)  # nothing dropped or reordered
    return scene


def _tie_rays():
    """Rays of known outcome: (origins, directions, {kind: ray mask}); kind "ab" crosses A and B at the
    same distance (from above, straight and slanted, and from below), "a" / "b" / "c" hit that triangle
    first with no other at that distance, "miss" nothing."""
    overlap = [(x, y) for x in (0.625, 0.75, 0.875, 1.0) for y in (0.625, 0.75, 0.875, 1.0) if x + y < 1.9]
    down, up, slant = (0.0, 0.0, -1.0), (0.0, 0.0, 1.0), (0.25, -0.125, -1.0)
    rays = {
        "ab": [((x, y, 1.0), down) for x, y in overlap]
        + [((x - 0.25, y + 0.125, 1.0), slant) for x, y in overlap]
        + [((x, y, -0.25), up) for x, y in overlap],
        "a": [((x, y, 1.0), down) for x, y in [(0.25, 0.25), (0.25, 1.25), (1.25, 0.25)]],
        "b": [((x, y, 1.0), down) for x, y in [(2.0, 0.75), (0.75, 2.0), (1.5, 1.0)]],
        "c": [((x, y, -1.0), up) for x, y in [(0.25, 0.25), (1.25, 0.25)]],
        "miss": [((0.75, 0.75, 1.0), up), ((5.0, 5.0, 1.0), down)],
    }
    o = np.array([r[0] for v in rays.values() for r in v], np.float32)
    d = np.array([r[1] for v in rays.values() for r in v], np.float32)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    kind = np.concatenate([[k] * len(v) for k, v in rays.items()])
    return jnp.asarray(o), jnp.asarray(d), {k: kind == k for k in rays}


def _expected_ok(tri_orig, t, kinds):
    """Ground truth per ray kind; ``tri_orig`` in TIE_TRIANGLES' numbering."""
    ok = np.zeros(tri_orig.shape, bool)
    ok[kinds["ab"]] = np.isin(tri_orig[kinds["ab"]], (A, B))
    for k, want in (("a", A), ("b", B), ("c", C), ("miss", -1)):
        ok[kinds[k]] = tri_orig[kinds[k]] == want
    return ok & (np.isfinite(t) == (tri_orig >= 0))


@pytest.fixture(scope="module")
def tie_hits():
    """Per triangle order: the scene and every backend's closest hits for :func:`_tie_rays`."""
    o, d, _ = _tie_rays()
    out = {}
    for order in ORDERS:
        scene = _tie_scene(order)
        casters = {
            "embree": EmbreeCaster(scene, threads=1),
            "bvh": BVHCaster(scene, lanes=16),
            "bvh-fused": BVHCaster(scene, schedule="fused", lanes=16),
            "brute": BruteForceCaster(scene),
        }
        out[order] = scene, {k: c.closest_hit(o, d) for k, c in casters.items()}
    return out


@pytest.mark.parametrize("order", ORDERS, ids=lambda o: "".join("ABC"[i] for i in o))
def test_backends_agree_whichever_tied_triangle_they_report(tie_hits, order):
    o, d, kinds = _tie_rays()
    scene, hits = tie_hits[order]
    perm = np.asarray(order)
    base_scene, base_hits = tie_hits[ORDERS[0]]
    for name, hit in hits.items():
        tri, t = np.asarray(hit.tri), np.asarray(hit.t)
        tri_orig = np.where(tri >= 0, perm[np.maximum(tri, 0)], -1)
        ok = _expected_ok(tri_orig, t, kinds)
        assert ok.all(), f"{name}: rays {np.flatnonzero(~ok)} report {tri_orig[~ok]} at t={t[~ok]}"
        h = tri >= 0
        np.testing.assert_array_equal(np.asarray(hit.material)[h], tri_orig[h], err_msg=name)
        if name != "embree":
            assert_same_hits(scene, o, d, hit, hits["embree"], label=name)
        # the same rays in the first order's scene (triangle ids mapped back): the order changes nothing
        # but, at most, which tied triangle is reported
        base = base_hits[name]
        c = compare_hits(base_scene.triangles, o, d, tri_orig, t, np.asarray(base.tri), np.asarray(base.t))
        assert c.agree.all(), f"{name}: order {order} disagrees with order {ORDERS[0]}"


def test_tie_check_accepts_only_verified_ties(tie_hits):
    """The tie check fires where it must (A and B at the same distance) and nowhere else: a triangle the
    ray misses, or crosses at another distance, is rejected — directly and through assert_same_hits."""
    o, d, kinds = _tie_rays()
    scene, hits = tie_hits[ORDERS[0]]
    tris = np.asarray(scene.triangles, np.float64)
    n = o.shape[0]
    full = lambda i: np.full(n, i)
    ab, a_only = kinds["ab"], kinds["a"]
    # every overlap ray is a verified A/B tie; a ray that crosses A alone is not
    assert verified_ties(tris, o, d, full(A), full(B))[ab].all()
    assert not verified_ties(tris, o, d, full(A), full(B))[a_only].any()
    # C: crossed by the downward overlap rays, but 0.5 further on; a deliberately wrong triangle
    same, ok = tie_or_same(scene, o, d, full(A), full(C))
    assert not same.any() and not ok.any()
    same, ok = tie_or_same(scene, o, d, full(A), full(B))
    assert not same.any() and np.array_equal(ok, ab)

    ref = hits["embree"]
    tri_ref = np.asarray(ref.tri)

    def swapped(new_tri):  # Embree's distances and barycentrics with other triangle ids
        return complete_hit(scene, ref.t, jnp.asarray(new_tri, jnp.int32), ref.bary)

    # the other tied triangle on every overlap ray: accepted, and the same-id share says so
    other = np.where(ab, np.where(tri_ref == A, B, A), tri_ref)
    c = assert_same_hits(scene, o, d, swapped(other), ref, label="other tied triangle")
    assert c.tie[ab].all() and c.same_id_share == pytest.approx(1.0 - ab.mean())
    # C on the overlap rays (at the tied distance): not a tie, rejected
    wrong = np.where(ab, C, tri_ref)
    with pytest.raises(AssertionError, match="not a verified coplanar tie"):
        assert_same_hits(scene, o, d, swapped(wrong), ref, label="wrong triangle")
    # B on the rays that cross A alone: rejected
    wrong = np.where(a_only, B, tri_ref)
    with pytest.raises(AssertionError, match="not a verified coplanar tie"):
        assert_same_hits(scene, o, d, swapped(wrong), ref, label="missed triangle")
    # a different distance at a tie: rejected by the distance check
    t_off = np.where(ab, np.asarray(ref.t) + 0.01, np.asarray(ref.t))
    shifted = complete_hit(scene, jnp.asarray(t_off, ref.t.dtype), jnp.asarray(other, jnp.int32), ref.bary)
    with pytest.raises(AssertionError):
        assert_same_hits(scene, o, d, shifted, ref, label="shifted")
    assert not compare_hits(tris, o, d, other, t_off, tri_ref, np.asarray(ref.t)).agree[ab].any()


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
    assert isinstance(make_caster(cornell, use="jit"), BruteForceCaster)
    assert isinstance(make_caster(load_scene("courtyard"), use="jit"), BVHCaster)
    assert isinstance(make_caster(cornell, "bvh", lanes=16), BVHCaster)
    assert make_caster(cornell, "embree", threads=1).threads == 1
    with pytest.raises(ConfigError, match="unknown ray-casting backend"):
        make_caster(cornell, "optix")
    with pytest.raises(ConfigError, match="cannot be jitted"):
        make_caster(cornell, "embree", use="jit")
    with pytest.raises(ConfigError, match="schedule"):
        BVHCaster(cornell, schedule="wide")
