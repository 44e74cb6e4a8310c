"""Valid space: region parsing and membership, default clearance, projection, relocation, drops.

Oracles: a hand-made SDF of one solid box (closed-form signed distance on the lattice, so the nearest face
and the distance to it are known exactly), and the Cornell box for the default clearance and a real SDF.
"""

from __future__ import annotations

import json

import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import ConfigError
from probeplace.geometry import SDFGrid, build_sdf, lookup_sdf
from probeplace.placement.baselines import _uniform
from probeplace.placement.space import _valid
from probeplace.placement.space._region import Region
from probeplace.placement.space._valid import default_clearance, make_valid, valid_candidates

# Hand-made scene: the unit box [0, 1]³ (placement box) holding one solid box.
LO, HI = np.zeros(3), np.ones(3)
SOLID_LO, SOLID_HI = np.array([0.3, 0.2, 0.3]), np.array([0.7, 0.6, 0.7])
H = 0.02  # voxel size
C = 2 * H  # clearance


def box_sdf(p, lo, hi):
    """Closed-form signed distance to the solid box [lo, hi] (negative inside)."""
    c, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    q = np.abs(p - c) - half
    return np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(-1), 0.0)


def grid_of(lo, hi, pad=0.1):
    """An SDFGrid sampling box_sdf(lo, hi) over [-pad, 1 + pad]³ at spacing H."""
    n = round((1 + 2 * pad) / H) + 1
    ax = -pad + H * np.arange(n)
    pts = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), axis=-1)
    return SDFGrid(
        values=jnp.asarray(box_sdf(pts, lo, hi), jnp.float32),
        origin=jnp.full(3, -pad, jnp.float32),
        voxel_size=jnp.asarray(H, jnp.float32),
    )


@pytest.fixture(scope="module")
def sdf():
    return grid_of(SOLID_LO, SOLID_HI)


@pytest.fixture(scope="module")
def cornell_sdf(cornell):
    return build_sdf(cornell, cache_dir=False)


# ------------------------------------------------------------------------------------ region
@pytest.mark.parametrize(
    ("value", "key"),
    [
        ([1, 2], "region must be"),
        ({"box": []}, "unknown key.*box"),
        ({"boxes": 3}, "region.boxes"),
        ({"boxes": [[[0, 0, 0]]]}, r"region.boxes\[0\]"),
        ({"boxes": [[[0, 0, 0], [1, 1, 1]], [[0, 0, 0], [1, 1]]]}, r"region.boxes\[1\]\[1\]"),
        ({"boxes": [[[0, 0, 0], [1, 0, 1]]]}, r"region.boxes\[0\] needs lo < hi"),
        ({"boxes": [[[0, 0, "a"], [1, 1, 1]]]}, r"region.boxes\[0\]\[0\]"),
        ({"height": [2.0, 1.0]}, "region.height"),
        ({"height": "tall"}, "region.height"),
        ({"height": [0.0, float("nan")]}, "region.height"),
        ({"floor": "ground"}, "region.floor"),
        ({"floor": True}, "region.floor"),
    ],
)
def test_region_config_errors_name_the_key(value, key):
    with pytest.raises(ConfigError, match=key):
        Region.from_config(value)


def test_region_parse_and_round_trip():
    assert Region.from_config(None) == Region.from_config({}) == Region.from_config({"boxes": []}) == Region()
    assert Region().is_everywhere and Region().to_config() is None
    r = Region.from_config({"boxes": [[[0, 0, 0], [1, 2, 3]]], "height": [0.5, 2], "floor": -1})
    assert r.boxes == (((0.0, 0.0, 0.0), (1.0, 2.0, 3.0)),) and r.height == (0.5, 2.0) and r.floor == -1.0
    assert Region.from_config(json.loads(json.dumps(r.to_config()))) == r
    assert Region.from_config(r) is r
    hash(r)  # frozen and hashable (float tuples)


def test_region_contains_boxes_and_height_band():
    r = Region.from_config({"boxes": [[[0, 0, 0], [1, 1, 1]], [[2, 0, 0], [3, 1, 1]]], "height": [0.5, 2.0]})
    pts = np.array(
        [
            [0.5, 0.6, 0.5],  # box 0, in the band
            [0.5, 0.4, 0.5],  # box 0, below the band
            [1.5, 0.6, 0.5],  # between the boxes
            [2.5, 0.75, 0.5],  # box 1
            [0.5, 1.0, 0.5],  # on box 0's top face (boundaries count)
            [0.5, 0.5, 0.5],  # on the band's lower edge
            [2.5, 0.75, 1.5],  # beyond box 1 in z
        ]
    )
    np.testing.assert_array_equal(r.contains(pts, floor=0.0), [1, 0, 0, 1, 1, 1, 0])
    # the floor moves the band: floor 0.2 → y in [0.7, 2.2]
    np.testing.assert_array_equal(r.contains(pts, floor=0.2), [0, 0, 0, 1, 1, 0, 0])
    with pytest.raises(ValueError, match="floor"):
        r.contains(pts)
    # a region floor wins over the argument
    rf = Region.from_config({"height": [0.5, 2.0], "floor": 0.2})
    np.testing.assert_array_equal(rf.contains(pts, floor=0.0), [0, 0, 0, 1, 1, 0, 1])
    assert Region().contains(pts * 100).all()
    assert r.contains(pts.reshape(7, 1, 3), floor=0.0).shape == (7, 1)


# ------------------------------------------------------------------------------------ clearance
def test_default_clearance(cornell, cornell_sdf):
    c = default_clearance(cornell, cornell_sdf)
    h = float(cornell_sdf.voxel_size)
    lo, hi = np.asarray(cornell.bounds, np.float64)
    assert c > 0 and c >= h
    assert c == max(2 * h, float(np.min(hi - lo)) / 128)
    # a finer SDF than the default: the box term keeps the clearance at the scene's scale
    fine = grid_of(SOLID_LO, SOLID_HI)
    assert default_clearance(None, fine, bounds=(LO, 100 * HI)) == pytest.approx(100 / 128)
    assert default_clearance(None, fine, bounds=(LO, HI)) == pytest.approx(2 * H)


# ------------------------------------------------------------------------------------ make_valid
def test_probe_inside_solid_moves_out_by_the_closest_face(sdf):
    # depth 0.05 below the solid's bottom face (y = 0.2); every other face is ≥ 0.2 away
    p = np.array([[0.5, 0.25, 0.5], [0.52, 0.58, 0.47]], np.float32)  # the second: 0.02 below the top
    r = make_valid(sdf, p, clearance=C, lo=LO, hi=HI)
    assert r.relocated.all() and r.moved.all() and not r.dropped.any() and not r.projected.any()
    assert r.n_relocated == r.n_moved == 2 and r.n_dropped == 0
    q = r.pos.astype(np.float64)
    assert r.pos.dtype == np.float32
    assert np.all(lookup_sdf(sdf, r.pos).astype(np.float64) >= C)
    # the closed-form distance agrees: clear of the solid by the clearance, up to the trilinear error of
    # the lattice (≤ h√3/2, docs/sdf.md; here the face is axis-aligned and the SDF linear: ~float eps)
    assert np.all(box_sdf(q, SOLID_LO, SOLID_HI) >= C - 1e-5)
    # it went through the closest face, straight (Newton steps on a linear SDF land at 1.5 × clearance)
    depth = np.array([0.05, 0.02])
    step = np.linalg.norm(q - p, axis=1)
    np.testing.assert_allclose(step, depth + 1.5 * C, atol=1e-5)  # float32 positions, ~1e-7 each
    assert q[0, 1] < SOLID_LO[1] and q[1, 1] > SOLID_HI[1]
    np.testing.assert_allclose(q[:, [0, 2]], p[:, [0, 2]], atol=1e-6)


def test_free_probes_untouched_bit_identical(sdf):
    for dtype in (np.float32, np.float64):
        p = np.array([[0.1, 0.8, 0.1], [0.5, 0.25, 0.5], [0.9, 0.1, 0.3]], dtype)
        r = make_valid(sdf, p, clearance=C, lo=LO, hi=HI)
        assert r.pos.dtype == dtype
        np.testing.assert_array_equal(r.moved, [False, True, False])
        assert r.pos[[0, 2]].tobytes() == p[[0, 2]].tobytes()
        assert r.pos is not p
    # a probe exactly on the clearance is valid
    on = np.array([[0.5, SOLID_HI[1] + 0.05, 0.5]], np.float32)
    assert not make_valid(sdf, on, clearance=float(lookup_sdf(sdf, on)[0]), lo=LO, hi=HI).moved.any()


def test_probe_with_no_escape_is_dropped():
    solid = grid_of(np.full(3, -5.0), np.full(3, 6.0))  # a solid filling the placement box and beyond
    p = np.array([[0.5, 0.5, 0.5], [0.1, 0.9, 0.2]], np.float32)
    r = make_valid(solid, p, clearance=C, lo=LO, hi=HI)
    assert r.dropped.all() and r.n_dropped == 2 and r.n_moved == 0 and not r.relocated.any()
    np.testing.assert_array_equal(r.pos, p)  # dropped rows keep the input
    assert r.record()["n_dropped"] == 2 and not r.valid.any()


def test_projection_into_height_band_and_box(sdf):
    region = {"height": [0.7, 0.9]}  # floor = lo[1] = 0 → y in [0.7, 0.9]
    p = np.array([[0.1, 0.2, 0.1], [0.1, 0.8, 0.1], [1.3, 0.95, -0.2]], np.float32)
    r = make_valid(sdf, p, clearance=C, region=region, lo=LO, hi=HI)
    np.testing.assert_array_equal(r.projected, [True, False, True])
    assert not r.relocated.any() and not r.dropped.any()
    # nearest point: clamp y (and x, z into the box), rounded inward to float32
    np.testing.assert_allclose(r.pos, [[0.1, 0.7, 0.1], [0.1, 0.8, 0.1], [1.0, 0.9, 0.0]], atol=1e-7)
    assert Region.from_config(region).contains(r.pos, floor=0.0).all()
    assert np.all((r.pos >= LO) & (r.pos <= HI))
    rec = r.record()
    assert rec["n_projected"] == 2 and rec["region"]["height"] == [0.7, 0.9]
    json.dumps(rec)


def test_projection_then_relocation_stays_in_region(sdf):
    # projected up to y = 0.3 lands 0.1 inside the solid; the nearest exit (the bottom face) is outside
    # the band, so the probe leaves sideways (faces 0.2 away) and stays at y ≥ 0.3
    p = np.array([[0.5, 0.25, 0.5]], np.float32)
    r = make_valid(sdf, p, clearance=C, region={"height": [0.3, 1.0]}, lo=LO, hi=HI)
    assert r.projected[0] and r.relocated[0] and r.moved[0] and not r.dropped[0]
    q = r.pos[0].astype(np.float64)
    assert q[1] >= 0.3 and box_sdf(q, SOLID_LO, SOLID_HI) >= C - 1e-5
    assert float(lookup_sdf(sdf, r.pos)[0]) >= C
    # the directional search's resolution: 128 directions (≤ ~10° off the face normal) and half-voxel radii
    start = np.array([0.5, 0.3, 0.5])
    assert np.linalg.norm(q - start) <= (0.2 + 1.5 * C) / np.cos(np.radians(12)) + H


def test_relocation_across_region_boxes(sdf):
    # two region boxes; the probe is in the second (which holds the solid's top half) and leaves through
    # the top face, staying in its box
    region = {"boxes": [[[0, 0, 0], [0.2, 1, 1]], [[0.25, 0.4, 0.25], [0.75, 1, 0.75]]]}
    p = np.array([[0.5, 0.55, 0.5], [0.1, 0.5, 0.5]], np.float32)
    r = make_valid(sdf, p, clearance=C, region=region, lo=LO, hi=HI)
    assert r.relocated[0] and not r.moved[1] and not r.dropped.any()
    np.testing.assert_allclose(r.pos[0], [0.5, SOLID_HI[1] + 1.5 * C, 0.5], atol=1e-5)
    assert Region.from_config(region).contains(r.pos, floor=0.0).all()


def test_make_valid_bad_inputs(sdf):
    p = np.array([[0.5, 0.5, 0.5]], np.float32)
    with pytest.raises(ConfigError, match="clearance"):
        make_valid(sdf, p, clearance=0.0, lo=LO, hi=HI)
    with pytest.raises(ConfigError, match="placement box"):
        make_valid(sdf, p, clearance=C, lo=HI, hi=LO)
    with pytest.raises(ConfigError, match="does not overlap"):
        make_valid(sdf, p, clearance=C, region={"boxes": [[[2, 2, 2], [3, 3, 3]]]}, lo=LO, hi=HI)
    with pytest.raises(ValueError, match="pos"):
        make_valid(sdf, p[0], clearance=C, lo=LO, hi=HI)
    with pytest.raises(ValueError, match="NaN"):
        make_valid(sdf, np.full((1, 3), np.nan, np.float32), clearance=C, lo=LO, hi=HI)


def test_cornell_probes_in_blocks(cornell, cornell_sdf):
    lo, hi = np.asarray(cornell.bounds, np.float64)
    c = default_clearance(cornell, cornell_sdf)
    rng = np.random.default_rng(0)
    p = (lo + (hi - lo) * rng.uniform(0.02, 0.98, (64, 3))).astype(np.float32)
    r = make_valid(cornell_sdf, p, clearance=c, lo=lo, hi=hi)
    before = lookup_sdf(cornell_sdf, p).astype(np.float64)
    assert (before < 0).any()  # some start inside a block
    np.testing.assert_array_equal(r.relocated, before < c)
    assert r.n_dropped == 0
    assert np.all(lookup_sdf(cornell_sdf, r.pos).astype(np.float64) >= c)
    assert np.all((r.pos >= lo) & (r.pos <= hi))
    assert r.pos[~r.moved].tobytes() == p[~r.moved].tobytes()


# ------------------------------------------------------------------------------------ candidates
def test_valid_candidates(sdf):
    region = {"boxes": [[[0, 0, 0], [1, 1, 0.5]]], "height": [0.1, 0.9]}
    pts = valid_candidates(sdf, LO, HI, C, region, 0.1)
    assert pts.dtype == np.float32 and pts.shape[1] == 3 and len(pts) > 0
    assert Region.from_config(region).contains(pts, floor=0.0).all()
    assert np.all(lookup_sdf(sdf, pts).astype(np.float64) >= C)
    # brute force: the region's bounding box [0,1]×[0.1,0.9]×[0,0.5] gets a centred lattice of 10×8×5;
    # the kept points are exactly those clear of the solid by C (closed form; lattice points are ≥ 0.01
    # from the tie, far beyond the lattice error)
    ax = [0.05 + 0.1 * np.arange(10), 0.15 + 0.1 * np.arange(8), 0.05 + 0.1 * np.arange(5)]
    z, y, x = np.meshgrid(ax[2], ax[1], ax[0], indexing="ij")
    lat = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    want = lat[box_sdf(lat, SOLID_LO, SOLID_HI) >= C]
    np.testing.assert_allclose(pts, want, atol=1e-6)
    whole = valid_candidates(sdf, LO, HI, C, None, 0.25)  # 4³ at 0.125 + 0.25 k, 8 of them in the solid
    assert len(whole) == 64 - 8 and np.all(box_sdf(whole.astype(np.float64), SOLID_LO, SOLID_HI) >= C)
    with pytest.raises(ConfigError, match="spacing"):
        valid_candidates(sdf, LO, HI, C, None, 0.0)


# ------------------------------------------------------------------------------------ uniform grid
def test_uniform_relocation_is_the_shared_one(sdf):
    assert _uniform.relocate_out is _valid.relocate_out
    r = _uniform.uniform_probe_grid(bounds=(LO, HI), dims=(5, 5, 5), inside="relocate", sdf=sdf)
    assert r.n_inside > 0 and r.n_relocated == r.n_inside and r.n_failed == 0
    assert np.all(lookup_sdf(sdf, np.asarray(r.probes.pos_world)[r.relocated]) > H)


def test_relocation_counts_share_a_compilation(sdf):
    # rows are padded to a power of two ≥ 8: 1 and 5 probes, and a new clearance, reuse one trace
    def n_traces():
        return _valid._relocate_points._cached._cache_size()

    inside = np.array([[0.5, 0.25, 0.5]], np.float32)
    make_valid(sdf, inside, clearance=C, lo=LO, hi=HI)
    n = n_traces()
    r = make_valid(sdf, np.repeat(inside, 5, axis=0), clearance=1.5 * C, lo=LO, hi=HI)
    assert n_traces() == n and r.n_relocated == 5
