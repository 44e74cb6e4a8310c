"""Vardis et al. 2021 simplification: batched local scoring against a rebuild-everything NumPy oracle."""

import jax
import numpy as np
import pytest
from scipy.spatial import Delaunay, cKDTree

from probeplace._core import ConfigError
from probeplace.placement import (
    dense_probe_sh,
    error_features,
    evaluation_points,
    leave_one_out_scores,
    poisson_disk_probes,
    vardis_simplify,
)
from probeplace.placement.baselines._tetra import TetMesh
from probeplace.placement.baselines._vardis import WEIGHT_PRESETS, Y00, YCOCG


def _interp(pos, pts):
    """Slow oracle: full Delaunay of ``pos``; barycentric weights by solving each (tet, point) system
    (np.linalg.solve, first containing tet), nearest probe outside the hull."""
    simp = Delaunay(pos).simplices
    v = pos[simp]  # (t, 4, 3)
    a = np.broadcast_to(np.moveaxis(v[:, :3] - v[:, 3:], 1, 2)[:, None], (len(simp), len(pts), 3, 3))
    l3 = np.linalg.solve(a, (pts[None] - v[:, None, 3])[..., None])[..., 0]
    lam = np.concatenate([l3, 1 - l3.sum(-1, keepdims=True)], -1)  # (t, p, 4)
    inside = lam.min(-1) >= -1e-12
    idx = np.zeros((len(pts), 4), np.int64)
    w = np.zeros((len(pts), 4))
    near = cKDTree(pos).query(pts)[1]
    for i in range(len(pts)):
        t = np.flatnonzero(inside[:, i])
        if len(t):
            idx[i], w[i] = simp[t[0]], lam[t[0], i]
        else:
            idx[i, 0], w[i, 0] = near[i], 1.0
    return idx, w


def _oracle_error(pos, vals, pts, keep, mode="sh", weights="chrominance"):
    """Mean weighted YCoCg error of the ``keep`` subset's interpolation against the full set's (docstring
    of _vardis), by rebuilding the Delaunay tetrahedralisation."""
    feat = error_features(vals, mode)
    idx, w = _interp(pos, pts)
    ref = np.einsum("pk,pkmc->pmc", w, feat[idx])
    lum = np.einsum("pk,pk->p", w, (vals[:, 0] * Y00 @ YCOCG.T)[:, 0][idx])
    den = np.maximum(np.abs(lum), 1e-3 * np.mean(np.abs(lum)))
    ids = np.flatnonzero(keep)
    idx2, w2 = _interp(pos[ids], pts)
    val = np.einsum("pk,pkmc->pmc", w2, feat[ids][idx2])
    wy, wcc = WEIGHT_PRESETS[weights]
    wc = np.array([wy, wcc, wcc])
    return float(np.mean(np.mean((np.abs(val - ref) * wc).sum(-1), -1) / den))


def _random_setup(seed, n=30, p=60):
    rng = np.random.default_rng(seed)
    pos = rng.uniform(0, 1, (n, 3))
    vals = rng.uniform(0, 1, (n, 9, 3))
    vals[:, 0] += 2.0  # positive mean luminance
    pts = rng.uniform(-0.1, 1.1, (p, 3))  # some outside the hull
    return pos, vals, pts


@pytest.mark.isa
@pytest.mark.parametrize("mode", ["sh", "directions", "average"])
def test_batched_scores_match_rebuild(mode):
    pos, vals, pts = _random_setup(0)
    batched = leave_one_out_scores(pos, vals, pts, error=mode)
    oracle = np.array(
        [_oracle_error(pos, vals, pts, np.arange(len(pos)) != v, mode) for v in range(len(pos))]
    )
    np.testing.assert_allclose(batched, oracle, rtol=1e-4, atol=1e-6)  # float32 scoring vs float64
    assert np.argmin(batched) == np.argmin(oracle)


@pytest.mark.isa
def test_greedy_order_matches_rebuild_greedy():
    """The cached, locally updated loop removes the same probes as greedy with full rebuilds."""
    pos, vals, pts = _random_setup(1, n=24, p=50)
    res = vardis_simplify(pos, vals, pts, target=14, tet_jitter=0.0)
    keep = np.ones(len(pos), bool)
    order = []
    for _ in range(10):
        cand = np.flatnonzero(keep)
        errs = []
        for v in cand:
            k = keep.copy()
            k[v] = False
            errs.append(_oracle_error(pos, vals, pts, k))
        v = int(cand[int(np.argmin(errs))])
        keep[v] = False
        order.append(v)
    np.testing.assert_array_equal(res.removal_order, order)
    np.testing.assert_array_equal(res.keep, keep)
    np.testing.assert_allclose(res.error, _oracle_error(pos, vals, pts, keep), rtol=2e-3)  # float32 (above)
    assert list(res.history_count) == list(range(24, 13, -1))


def test_independent_set_removal():
    pos, vals, pts = _random_setup(2, n=60, p=120)
    res = vardis_simplify(pos, vals, pts, target=20, per_iteration=8)
    assert res.keep.sum() == 20 and res.n_iterations < 40
    # scores of non-interacting removals add up: the tracked error is the true error of the survivors
    # float32 scoring: |interpolated − reference| cancels ~eps32·|feature| per point, ~1e-4 of the error
    np.testing.assert_allclose(res.error, _oracle_error(pos, vals, pts, res.keep), rtol=2e-3)
    one = vardis_simplify(pos, vals, pts, target=20)
    assert one.n_iterations == 40
    # lazy greedy: fewer candidate evaluations, and its bookkeeping still tracks the true error
    lz = vardis_simplify(pos, vals, pts, target=20, lazy=True)
    assert lz.keep.sum() == 20 and lz.n_scored < one.n_scored
    np.testing.assert_allclose(lz.error, _oracle_error(pos, vals, pts, lz.keep), rtol=2e-3)


def test_tolerance_and_mesh_invariants():
    pos, vals, pts = _random_setup(3, n=40, p=80)
    res = vardis_simplify(pos, vals, pts, tolerance=0.05)
    assert res.error <= 0.05 and res.keep.sum() >= 4
    # one more removal would have exceeded the tolerance (or nothing was left to remove)
    if res.keep.sum() > 4:
        nxt = min(
            _oracle_error(pos, vals, pts, res.keep & (np.arange(len(pos)) != v))
            for v in np.flatnonzero(res.keep)
        )
        assert nxt > 0.05 - 1e-5
    mesh = TetMesh(pos, pts)
    for v in (0, 5, 9):
        mesh.apply(mesh.plan_removal(v))
    ids = np.flatnonzero(mesh.alive)
    idx, w = _interp(pos[ids], pts)
    np.testing.assert_allclose(
        (w[:, :, None] * pos[ids][idx]).sum(1), (mesh.w[:, :, None] * pos[mesh.idx]).sum(1), atol=1e-9
    )


def test_determinism_grid_input():
    """Same inputs → identical removal order; a grid (co-spherical points) works through tet_jitter."""
    g = np.stack(np.meshgrid(*[np.arange(5)] * 3, indexing="ij"), -1).reshape(-1, 3).astype(float)
    rng = np.random.default_rng(4)
    vals = rng.uniform(0, 1, (len(g), 9, 3))
    vals[:, 0] += 1.0
    pts = rng.uniform(0, 4, (100, 3))
    a = vardis_simplify(g, vals, pts, target=60)
    b = vardis_simplify(g, vals, pts, target=60)
    np.testing.assert_array_equal(a.removal_order, b.removal_order)
    assert a.keep.sum() == 60


def test_bad_input():
    pos, vals, pts = _random_setup(5, n=10, p=10)
    with pytest.raises(ConfigError, match="target"):
        vardis_simplify(pos, vals, pts, target=2)
    with pytest.raises(ConfigError, match="tolerance"):
        vardis_simplify(pos, vals, pts)
    with pytest.raises(ConfigError, match="values"):
        vardis_simplify(pos, vals[:, :4], pts, target=5)
    with pytest.raises(ConfigError, match="weights"):
        vardis_simplify(pos, vals, pts, target=5, weights="bright")
    with pytest.raises(ConfigError, match="error"):
        vardis_simplify(pos, vals, pts, target=5, error="mse")
    with pytest.raises(ConfigError, match="per_iteration"):
        vardis_simplify(pos, vals, pts, target=5, per_iteration=0)


def test_dense_probe_sh_light_from_above(cornell):
    """Invariants of the projection: radiance is non-negative, so the DC term is positive; the Cornell
    box's only emitter is in the ceiling (+Y up), so the Y1-1 (y) band of the luminance is positive."""
    pos = np.array([[278.0, 274.0, 280.0], [150.0, 300.0, 150.0]], np.float32)
    sh = np.asarray(dense_probe_sh(cornell, pos, n_dirs=64, spp=2, max_depth=3, key=jax.random.key(0)))
    assert sh.shape == (2, 9, 3) and sh.dtype == np.float32
    assert np.all(sh[:, 0] > 0)
    assert np.all((sh[:, 1] @ YCOCG.T)[:, 0] > 0)


def test_evaluation_points_kinds(cornell):
    key = jax.random.key(0)
    s = evaluation_points(cornell, 64, key=key, kind="surface")
    assert s.shape == (64, 3) and s.dtype == np.float32
    lo, hi = np.asarray(cornell.vertices).min(0), np.asarray(cornell.vertices).max(0)
    assert np.all(s > lo - 1) and np.all(s < hi + 1)
    path = np.array([[100.0, 100.0, 100.0], [400.0, 100.0, 100.0], [400.0, 300.0, 100.0]])
    p = evaluation_points(cornell, 50, key=key, kind="paths", paths=[path])
    assert np.allclose(p[:, 2], 100.0) and p.shape == (50, 3)
    arc = (p[:, 0] - 100.0) + (p[:, 1] - 100.0)  # arc length along this L-shaped polyline
    np.testing.assert_allclose(arc, (np.arange(50) + 0.5) * 10.0, atol=1e-3)  # 500 / 50, even by length
    with pytest.raises(ConfigError):
        evaluation_points(cornell, 5, key=key, kind="volume")
    q = poisson_disk_probes(cornell, 120.0, key=key)
    d = np.linalg.norm(q[:, None] - q[None], axis=-1) + np.eye(len(q)) * 1e9
    assert len(q) >= 10 and d.min() >= 120.0 * (1 - 1e-6)


@pytest.mark.isa
def test_vectorised_plans_match_single_plans():
    """TetMesh.plan_removals (geometry vectorised across candidates) == plan_removal one at a time."""
    rng = np.random.default_rng(6)
    pos, pts = rng.uniform(size=(40, 3)), rng.uniform(-0.1, 1.1, (150, 3))
    mesh = TetMesh(pos, pts)
    for step in range(5):
        ids = [v for v in range(len(pos)) if mesh.alive[v]]
        many = mesh.plan_removals(ids)
        for v, b in zip(ids, many, strict=True):
            a = mesh.plan_removal(v)
            assert a.vertex == b.vertex and a.touch == b.touch
            np.testing.assert_array_equal(a.points, b.points)
            np.testing.assert_array_equal(a.idx, b.idx)
            np.testing.assert_array_equal(a.point_tet, b.point_tet)
            np.testing.assert_allclose(a.w, b.w, atol=1e-12)
            if a.new_tets is not None and b.new_tets is not None:
                np.testing.assert_array_equal(a.new_tets, b.new_tets)
        mesh.apply(many[(7 * step) % len(many)])
