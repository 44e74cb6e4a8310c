"""The light-field tracer's cell cones and closed-form plane bounds (``probes.tracer._surfels``, issue 33)
against dense float64 samples of the cells they bound."""

from __future__ import annotations

import numpy as np
import pytest

from probeplace.probes.tracer._surfels import (
    NEIGHBOURS,
    _bounds,
    _octahedron_point64,
    _pair,
    cell_cones,
    neighbour_pairs,
)


def _cell_samples(m: int, rows, cols, k: int, rng) -> np.ndarray:
    """(len(rows), k + 4·k, 3) float64 unit directions inside cells (rows v, columns u) of the m×m
    octahedral grid: k random interior points and k points along each edge (corners included)."""
    h = 2.0 / m
    u0 = np.asarray(cols)[:, None] * h - 1.0
    v0 = np.asarray(rows)[:, None] * h - 1.0
    t = np.linspace(0.0, 1.0, k)[None, :]
    edge_u = np.concatenate([t, t, np.zeros_like(t), np.ones_like(t)], axis=1)
    edge_v = np.concatenate([np.zeros_like(t), np.ones_like(t), t, t], axis=1)
    fu = np.concatenate([rng.uniform(size=(len(rows), k)), np.broadcast_to(edge_u, (len(rows), 4 * k))], 1)
    fv = np.concatenate([rng.uniform(size=(len(rows), k)), np.broadcast_to(edge_v, (len(rows), 4 * k))], 1)
    return _octahedron_point64(u0 + fu * h, v0 + fv * h)


@pytest.mark.isa
@pytest.mark.parametrize("m", [4, 16, 64])
def test_cell_cones_contain_their_cells_and_no_more(m):
    """Every direction of a cell lies within its cone (dense float64 samples: 64 interior points and 64
    along each edge, the cells crossed by the fold |u| + |v| = 1 included), and the cone is no wider than
    the farthest sample by more than 2 % (the edge samples are h/63 apart; the angle moves by at most ~2h/63
    between two of them, well under 2 % of a cell's half-angle ~h)."""
    cones = np.asarray(cell_cones(m), np.float64)
    rng = np.random.default_rng(m)
    rows, cols = np.divmod(np.arange(m * m) if m <= 16 else rng.choice(m * m, 512, replace=False), m)
    w = _cell_samples(m, rows, cols, 64, rng)
    axis = np.moveaxis(cones[:3, rows, cols], 0, -1)
    theta = np.arccos(np.clip(cones[3, rows, cols], -1, 1))
    angle = np.arccos(np.clip(np.sum(w * axis[:, None, :], axis=-1), -1, 1)).max(axis=1)
    assert (angle <= theta).all(), float((angle - theta).max())
    assert (theta <= 1.02 * angle + 1e-6).all(), float((theta / angle).max())
    np.testing.assert_allclose(np.sin(theta), cones[4, rows, cols], atol=1e-6)


@pytest.mark.isa
def test_plane_bounds_hold_over_the_cell_and_are_tight_when_it_faces_the_probe():
    """``_bounds`` (float32, closed form over the cone) against each plane's radial distance d / (ω·n̂)
    sampled densely over the cell in float64: the lower bound is at most the nearest sample and the upper
    bound at least the farthest "deep behind" distance (d + τ) / (ω·n̂) (the outward rounding of 1e-4
    covers float32's ~1e-6 relative error); for planes within 45° of facing the cell at m = 64 the lower
    bound is within 5 % of the nearest sample (a circumscribed cone of half-angle θ ≈ 0.03 rad moves
    cos(α − θ) by at most tan(α)·θ ≈ 3 %)."""
    import jax.numpy as jnp

    m, k, n_planes = 64, 32, 400
    rng = np.random.default_rng(7)
    cones = np.asarray(cell_cones(m))
    rows, cols = rng.integers(0, m, n_planes), rng.integers(0, m, n_planes)
    axis = np.moveaxis(cones[:3, rows, cols], 0, -1).astype(np.float64)
    # Surfel points along the cell's axis, normals within ~80° of facing the probe (turned toward it).
    dist = rng.uniform(0.5, 20.0, n_planes)
    x = dist[:, None] * axis
    normal = -axis + rng.normal(size=(n_planes, 3)) * rng.uniform(0.0, 2.0, (n_planes, 1))
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    normal[np.sum(normal * axis, -1) > 0] *= -1
    thickness, big = 0.03, 1e6
    lo, hi = _bounds(
        jnp.asarray(x, jnp.float32),
        jnp.asarray(normal, jnp.float32),
        jnp.ones(n_planes, bool),
        jnp.asarray(cones[:, rows, cols]),
        thickness,
        big,
    )
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    w = _cell_samples(m, rows, cols, k, rng)
    d = np.abs(np.sum(x * normal, -1))[:, None]
    cos = np.sum(w * -normal[:, None, :], -1)  # ω·n̂ with n̂ turned away from the probe, toward x
    r = np.where(cos > 1e-9, d / np.where(cos > 1e-9, cos, 1.0), np.inf)
    tau = thickness * np.linalg.norm(x, axis=-1)[:, None]
    deep = np.where(cos > 1e-9, (d + tau) / np.where(cos > 1e-9, cos, 1.0), np.inf)
    assert (lo <= r.min(axis=1)).all()
    assert ((hi >= deep.max(axis=1)) | (hi == big)).all()
    assert (hi == big).any() and (hi < big).mean() > 0.5  # both kinds of cell occur
    facing = np.sum(-normal * axis, -1) > np.cos(np.pi / 4)
    assert facing.sum() > 50
    assert (lo[facing] >= 0.95 * r.min(axis=1)[facing]).all()


def test_neighbour_pairs_are_each_texels_own_tests():
    """``neighbour_pairs`` (each pair of texels tested once, read from both) against ``_pair`` (each texel
    against its neighbour at each of the eight offsets) on a Cornell-box probe's maps, whose blocks give
    silhouettes and creases of both kinds: the same flags, bit for bit. Run op by op (no jit): then both
    are the same IEEE operations on swapped operands, which the test is about; compiled, XLA may contract
    a multiply-add into an FMA in one program and not the other (an ulp at a tolerance's edge)."""
    import jax

    from probeplace.probes.tracer._trace import _geometry_maps
    from probeplace.scene import load_scene
    from tests.probes.test_trace import _bake

    scene = load_scene("cornell_box")
    lo, hi = np.asarray(scene.bounds[0]), np.asarray(scene.bounds[1])
    lf = _bake(scene, np.array([lo + (hi - lo) * [0.3, 0.45, 0.6]]), 16)
    x, n, h, wb = _geometry_maps(lf.distance, lf.normal, lf.far)
    xb, nb, hb = x[0], n[0], h[0]
    with jax.disable_jit():
        pairs = neighbour_pairs(xb, nb, hb, wb, 0.05)
        assert set(pairs) == set(NEIGHBOURS)
        for di, dj in NEIGHBOURS:
            for got, want in zip(pairs[di, dj], _pair(xb, nb, hb, wb, di, dj, 0.05), strict=True):
                np.testing.assert_array_equal(np.asarray(got), np.asarray(want), err_msg=f"{(di, dj)}")
        one = np.stack([np.asarray(pairs[o][0]) for o in NEIGHBOURS])
        concave = np.stack([np.asarray(pairs[o][1]) for o in NEIGHBOURS])
        assert not one.all() and concave.any()  # silhouettes and concave creases occur
    assert neighbour_pairs(xb, nb, hb, wb, None) == {}
