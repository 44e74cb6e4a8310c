"""Light-field tracer on the Cornell box with a 4×4×4 grid, against the exact brute-force caster (issue 4:
≥ 99% of resolved rays agree — same place within one texel's footprint or a point on scene geometry within
one texel of the true ray — and < 1% unresolved), and the invariant that the min-MIP hierarchies are
conservative (flat, two-level and hi-Z marches give identical answers). Apart from tests/probes/test_trace.py
(closed forms in an empty room, single quads and sheets) so that the two halves run on separate test
workers.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import ConfigError
from probeplace.geometry import BruteForceCaster
from probeplace.probes import TraceConfig, TraceStatus, make_tracer, trace_light_field
from probeplace.probes.tracer._index import grid_index, voxel_index
from probeplace.scene import load_scene

from .test_trace import R_CORNELL, _bake, _unit


# ------------------------------------------------------------------------------------ Cornell grid
@pytest.fixture(scope="module")
def cornell_grid():
    scene = load_scene("cornell_box")
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    g = (np.arange(4) + 0.5) / 4
    pos = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3) * (hi - lo) + lo
    return scene, pos, _bake(scene, pos, R_CORNELL)


def _shading_rays(scene, n, seed):
    """Secondary rays as shading makes them: from camera-visible surface points (offset along the normal)
    into the cosine-weighted hemisphere."""
    rng = np.random.default_rng(seed)
    cam = scene.views[0]
    pos, look = np.asarray(cam.position, np.float64), np.asarray(cam.look_at, np.float64)
    fwd = _unit(look - pos)
    right = _unit(np.cross(fwd, [0.0, 1.0, 0.0]))
    up = np.cross(right, fwd)
    tan = np.tan(np.radians(float(cam.fov_y_deg)) / 2)
    xy = rng.uniform(-1, 1, (n, 2)) * tan
    dc = _unit(fwd + xy[:, :1] * right + xy[:, 1:] * up)
    caster = BruteForceCaster(scene)
    h = caster.closest_hit(jnp.asarray(np.repeat(pos[None], n, 0), jnp.float32), jnp.asarray(dc, jnp.float32))
    ok = np.asarray(h.tri) >= 0
    p = pos + np.asarray(h.t, np.float64)[:, None] * dc
    nrm = np.asarray(h.geo_normal, np.float64)
    nrm = np.where((np.sum(nrm * dc, 1) > 0)[:, None], -nrm, nrm)
    p, nrm = p[ok], nrm[ok]
    m = len(p)
    u1, u2 = rng.uniform(size=m), rng.uniform(size=m)
    a = np.where(np.abs(nrm[:, :1]) > 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    tx = _unit(np.cross(nrm, a))
    ty = np.cross(nrm, tx)
    r, phi = np.sqrt(u1), 2 * np.pi * u2
    d = (r * np.cos(phi))[:, None] * tx + (r * np.sin(phi))[:, None] * ty + np.sqrt(1 - u1)[:, None] * nrm
    return jnp.asarray(p + 0.05 * nrm, jnp.float32), jnp.asarray(_unit(d), jnp.float32)


def _point_triangle_distance(p, tri):
    """Distance from points (m, 3) to triangles (k, 3, 3) → (m, k): slow, obvious reference (Ericson 2005,
    Real-Time Collision Detection §5.1.5: closest point is in the face or on an edge)."""
    a, b, c = (tri[None, :, i] for i in range(3))
    q = p[:, None]
    n = np.cross(b - a, c - a)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    dist_plane = np.sum((q - a) * n, -1)
    proj = q - dist_plane[..., None] * n
    inside = np.ones(proj.shape[:2], bool)
    for x, y in ((a, b), (b, c), (c, a)):
        inside &= np.sum(np.cross(y - x, proj - x) * n, -1) >= 0
    best = np.where(inside, np.abs(dist_plane), np.inf)
    for x, y in ((a, b), (b, c), (c, a)):
        e = y - x
        s = np.clip(np.sum((q - x) * e, -1) / np.sum(e * e, -1), 0, 1)
        best = np.minimum(best, np.linalg.norm(q - (x + s[..., None] * e), axis=-1))
    return best


def _agreement(scene, pos, res, o, d, out):
    """Per ray: does the light-field answer agree with exact casting (module docstring)?"""
    ex = BruteForceCaster(scene).closest_hit(o, d)
    o, d = np.asarray(o, np.float64), np.asarray(d, np.float64)
    st, t, probe = np.asarray(out.status), np.asarray(out.t, np.float64), np.asarray(out.probe)
    te = np.asarray(ex.t, np.float64)
    alpha = np.sqrt(4 * np.pi) / res  # a texel's mean angular size
    hit = st == TraceStatus.HIT
    p_lf = o + np.where(hit, t, 0.0)[:, None] * d
    p_ex = o + np.where(np.isfinite(te), te, 0.0)[:, None] * d
    r = np.linalg.norm(p_lf - pos[np.maximum(probe, 0)], axis=1)
    view = (p_lf - pos[np.maximum(probe, 0)]) / np.maximum(r, 1e-9)[:, None]
    cos = np.abs(np.sum(np.asarray(ex.geo_normal) * view, 1))
    footprint = r * alpha / np.maximum(cos, 0.1)  # a texel's footprint on the hit surface
    same_place = hit & np.isfinite(te) & (np.linalg.norm(p_lf - p_ex, axis=1) <= footprint)
    tris = np.asarray(scene.vertices, np.float64)[np.asarray(scene.faces)]
    d_geo = np.full(len(st), np.inf)
    d_geo[hit] = _point_triangle_distance(p_lf[hit], tris).min(axis=1)
    near_geometry = hit & (d_geo <= r * alpha)  # the ray passes within a texel of the surface found
    both_miss = (st == TraceStatus.MISS) & ~np.isfinite(te)
    return same_place | near_geometry | both_miss


def test_cornell_grid_agrees_with_exact_casting(cornell_grid):
    scene, pos, lf = cornell_grid
    o, d = _shading_rays(scene, 6000, seed=0)
    tr = make_tracer(lf, scene.bounds, config=TraceConfig(hierarchy="hiz"))
    out = trace_light_field(tr, o, d)
    resolved = np.asarray(out.status) != TraceStatus.UNRESOLVED
    agree = _agreement(scene, pos, R_CORNELL, o, d, out)
    # 2%, not 1% as before issue 16: the half-texels next to silhouettes (the blocks' edges, the box's
    # open front) are unknown rather than guessed; the probes that see the last free point resolve most.
    # Measured: 1.4% unresolved, 99.4% agreement (McGuire's one-surfel model: 0.8%, 99.6%).
    assert (~resolved).mean() < 0.02
    assert agree[resolved].mean() >= 0.99


@pytest.mark.slow  # 55 s on 2 cores (CI time): it compiles the two-level and flat marches too
def test_hierarchies_are_conservative(cornell_grid):
    """The min-MIP bounds only skip cells where every fine texel says "in front": same answers."""
    scene, _, lf = cornell_grid
    o, d = _shading_rays(scene, 600, seed=1)
    outs = {
        h: trace_light_field(make_tracer(lf, scene.bounds, config=TraceConfig(hierarchy=h)), o, d)
        for h in ("flat", "two_level", "hiz")
    }
    for h in ("two_level", "hiz"):
        np.testing.assert_array_equal(np.asarray(outs[h].status), np.asarray(outs["flat"].status))
        # rtol: the hit is the same plane crossing, computed from a cell interval split differently.
        np.testing.assert_allclose(np.asarray(outs[h].t), np.asarray(outs["flat"].t), rtol=1e-4)


@pytest.mark.slow  # 20 s on 2 cores (CI time)
def test_voxel_index_tracer_agrees(cornell_grid):
    scene, pos, lf = cornell_grid
    index = voxel_index(lf, scene.bounds, k=4, max_voxels_per_axis=8)
    cand = np.asarray(index.candidates)
    usable = np.asarray(lf.active) & ~np.asarray(lf.inside)
    assert np.all(cand[..., 0] >= 0)  # every voxel has a candidate
    assert np.all(usable[cand[cand >= 0]])
    o, d = _shading_rays(scene, 1500, seed=2)
    tr = make_tracer(lf, scene.bounds, index=index)
    out = trace_light_field(tr, o, d)
    resolved = np.asarray(out.status) != TraceStatus.UNRESOLVED
    # Looser than the grid test (1500 rays, not 6000: one ray is 0.07%; the fallback probes are not a
    # cage, so farther and coarser). Measured: 2.8% unresolved, 98.4% agreement.
    assert (~resolved).mean() < 0.035
    assert _agreement(scene, pos, R_CORNELL, o, d, out)[resolved].mean() >= 0.98


def test_unresolved_rays_are_flagged(cornell_grid):
    """With one probe allowed, rays hidden from it cannot be resolved: flagged, never passed off."""
    scene, _, lf = cornell_grid
    o, d = _shading_rays(scene, 400, seed=3)
    out = trace_light_field(make_tracer(lf, scene.bounds, config=TraceConfig(max_probes=1)), o, d)
    st = np.asarray(out.status)
    assert (st == TraceStatus.UNRESOLVED).any()
    assert np.all(np.asarray(out.probes_tried) <= 1)
    assert np.all(np.asarray(out.probe)[st != TraceStatus.HIT] == -1)


def test_grid_index_rejects_non_grid(cornell_grid):
    _, _, lf = cornell_grid
    moved = eqx.tree_at(lambda x: x.pos_world, lf, lf.pos_world.at[3].add(7.0))
    with pytest.raises(ConfigError, match="grid"):
        grid_index(moved)
    assert grid_index(lf).dims == (4, 4, 4)
