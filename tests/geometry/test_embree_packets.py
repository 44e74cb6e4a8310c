"""Embree's 16-ray packets (geometry/_embree_packets.py) against embreex's one ray at a time.

The two are different Embree traversal kernels over different BVH builds of the same triangles, so what
is judged is what :mod:`tests.geometry.raycast_reference` judges between any two casters (hit or miss,
the distance within float32 rounding, the triangle or a verified coplanar tie), except on rays that graze
an edge: Embree's triangle test is not watertight, and a ray through the crack between two triangles
may pass in one kernel and not in the other. Such rays are accepted only where the float64 Möller–Trumbore
test confirms the graze (the ray within ``GRAZE`` of an edge of the triangle either kernel reports) and
only as a tiny share of the rays.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import texel_directions
from probeplace.geometry import EmbreeCaster
from probeplace.geometry import _embree_packets as packets_mod
from probeplace.geometry._embree import _chunks, _the_hit
from probeplace.probes._bake import _to_tiles
from probeplace.scene import load_scene
from tests.geometry.raycast_reference import compare_hits, random_rays

SCENES = ["cornell_box", "temple", "rooms", "courtyard"]
GRAZE = 1e-5  # float64 barycentric margin of an edge graze (float32 corners: ~1e-7 relative)

needs_packets = pytest.mark.skipif(
    packets_mod._library() is None,
    reason="Embree packets unavailable: embreex's libembree4 or the _packet_loop extension (built at "
    "install where a C compiler is found) is missing; the Embree caster casts one ray at a time",
)


def _barycentric_margin(tris, o, d, tri):
    """float64 min(u, v, 1 − u − v) of ray i on triangle ``tri[i]`` (its plane crossing): negative
    outside the triangle, within ``GRAZE`` of 0 on an edge; NaN where ``tri`` is −1."""
    ok = tri >= 0
    out = np.full(tri.shape, np.nan)
    t = tris[tri[ok]]
    e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
    dd = np.asarray(d, np.float64)[ok]
    s = np.asarray(o, np.float64)[ok] - t[:, 0]
    p = np.cross(dd, e2)
    inv = 1.0 / np.sum(e1 * p, axis=1)
    u = np.sum(s * p, axis=1) * inv
    v = np.sum(dd * np.cross(s, e1), axis=1) * inv
    out[ok] = np.minimum(np.minimum(u, v), 1.0 - u - v)
    return out


def _tile_rays(scene, n_origins: int, res: int, seed: int):
    """The bake's rays: from each of ``n_origins`` random points, the texel-centre directions of a
    ``res``² octahedral map in 4×4 tiles (16 consecutive rays a tile)."""
    o, _ = random_rays(scene, n_origins, seed=seed)
    dirs = _to_tiles(np.asarray(texel_directions(res), np.float32))
    return np.repeat(np.asarray(o), len(dirs), axis=0), np.tile(dirs, (n_origins, 1))


def _judge(scene, o, d, got, ref):
    """Rays that disagree beyond a verified edge graze; and the number of grazes accepted."""
    tris = np.asarray(scene.vertices, np.float64)[np.asarray(scene.faces)]
    tri, t = np.asarray(got.tri), np.asarray(got.t)
    tri_r, t_r = np.asarray(ref.tri), np.asarray(ref.t)
    c = compare_hits(tris, o, d, tri, t, tri_r, t_r)
    off = np.flatnonzero(~c.agree)
    graze = np.zeros(off.size, bool)
    for side in (tri, tri_r):  # the triangle either kernel reports, crossed within GRAZE of an edge
        m = _barycentric_margin(tris, o[off], d[off], side[off])
        graze |= np.abs(m) <= GRAZE
    return off[~graze], int(graze.sum()), c


@needs_packets
@pytest.mark.parametrize("name", SCENES)
def test_packets_agree_with_single_rays(name):
    """Coherent tiles (the bake's rays) and random rays (packets of unrelated rays): every ray agrees
    with embreex's single-ray answer, or grazes an edge (at most 1 in 10⁴ of the rays)."""
    scene = load_scene(name)
    caster = EmbreeCaster(scene, threads=1)
    to, td = _tile_rays(scene, 4, 32, seed=11)
    ro, rd = (np.asarray(x) for x in random_rays(scene, 3001, seed=12))  # a short last packet
    o, d = np.concatenate([to, ro]), np.concatenate([td, rd])
    ref = caster.closest_hit(jnp.asarray(o), jnp.asarray(d))
    got = caster.closest_hit_map(_the_hit, o, d, coherent=True)
    assert 0.3 < float(np.asarray(ref.hit).mean()) <= 1.0  # the rays do meet the scene
    bad, grazes, c = _judge(scene, o, d, got, ref)
    assert bad.size == 0, f"{name}: rays {bad[:5]} disagree and graze no edge ({bad.size} of {len(o)})"
    assert grazes <= 1e-4 * len(o), f"{name}: {grazes} edge grazes of {len(o)} rays"
    # where the triangle is the same, so is the hit's completion (material, barycentrics within rounding)
    same = c.same_id & np.asarray(ref.hit)
    np.testing.assert_array_equal(np.asarray(got.material)[same], np.asarray(ref.material)[same])
    np.testing.assert_allclose(np.asarray(got.bary)[same], np.asarray(ref.bary)[same], atol=1e-4)


@needs_packets
def test_packets_respect_t_max_and_threads():
    """``t_max`` bounds the packets' hits as the single rays' (rays within rounding of it left out); the
    answers do not depend on the thread count (chunks keep each packet whole)."""
    scene = load_scene("rooms")
    o, d = _tile_rays(scene, 3, 64, seed=13)
    extent = float(np.linalg.norm(np.ptp(np.asarray(scene.vertices), axis=0)))
    full = np.asarray(EmbreeCaster(scene, threads=1).closest_hit(jnp.asarray(o), jnp.asarray(d)).t)
    t_max = np.random.default_rng(14).uniform(0.0, 0.6 * extent, len(o)).astype(np.float32)
    clear = np.abs(full - t_max) > 1e-5 * extent
    one, two = (
        EmbreeCaster(scene, threads=k).closest_hit_map(_the_hit, o, d, t_max=t_max, coherent=True)
        for k in (1, 2)
    )
    t = np.asarray(one.t)
    assert np.all(t[np.isfinite(t)] < t_max[np.isfinite(t)])
    np.testing.assert_array_equal(np.isfinite(t)[clear], (full < t_max)[clear])
    for a, b in zip(jax.tree.leaves(one), jax.tree.leaves(two), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_without_packets_the_coherent_query_is_the_single_ray_one(monkeypatch):
    """Where the packets are unavailable (no compiled loop), ``coherent=True`` casts through embreex: the
    very same answers as ``closest_hit``."""
    scene = load_scene("cornell_box")
    monkeypatch.setattr(packets_mod, "_LIB", [None])
    caster = EmbreeCaster(scene, threads=2)
    o, d = _tile_rays(scene, 2, 32, seed=15)
    got = caster.closest_hit_map(_the_hit, o, d, coherent=True)
    assert caster.handle.packets() is None
    ref = caster.closest_hit(jnp.asarray(o), jnp.asarray(d))
    for a, b in zip(jax.tree.leaves(got), jax.tree.leaves(ref), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


@pytest.mark.parametrize("n", [0, 1, 15, 16, 17, 16384, 100_003, 2_000_000])
@pytest.mark.parametrize("threads", [1, 2, 3])
def test_chunks_keep_packets_whole(n, threads):
    """Whole packets, in order, no ray twice; no empty slice (a batch of 0 rays is one empty slice)."""
    parts = _chunks(n, threads, 16)
    covered = np.concatenate([np.arange(sl.start, sl.stop) for sl in parts])
    np.testing.assert_array_equal(covered, np.arange(n))
    assert all(sl.start % 16 == 0 for sl in parts)
    assert all(sl.stop > sl.start for sl in parts) if n else parts == [slice(0, 0)]
