"""The baselines as ``place`` methods (grid, lod-grid, vardis) and the ``probeplace place`` options."""

import json

import numpy as np
import pytest

from probeplace._core import ConfigError, scene_box
from probeplace.cli import main
from probeplace.placement import lod_probe_grid, place, uniform_probe_grid


def _placed(scene, **kw):
    """``place`` as (probes, metadata record): what these tests check."""
    res = place(scene, **kw)
    return res.probes, res.metadata


def test_grid_method_matches_uniform_grid(cornell):
    probes, meta = _placed(cornell, method="grid", options={"dims": (3, 3, 3), "inside": "disable"})
    r = uniform_probe_grid(cornell, dims=(3, 3, 3), inside="disable")
    expect = np.asarray(r.probes.pos_world)[np.asarray(r.probes.active)]
    np.testing.assert_array_equal(np.asarray(probes.pos_world), expect)
    assert probes.method == "grid" and meta["n_probes"] == len(expect)
    assert meta["config"]["dims"] == [3, 3, 3] and 0.0 < meta["coverage"] <= 1.0
    assert meta["n_disabled"] == r.n_disabled and "total_s" in meta["timings"]


def test_grid_method_offset_shifts_the_lattice(cornell):
    """An ``offset`` of (0.25, 0, 0.5) cells moves every probe by exactly that many cell widths (keep all)."""
    opts = {"dims": (3, 3, 3), "inside": "keep"}
    base, _ = _placed(cornell, method="grid", options=opts)
    moved, meta = _placed(cornell, method="grid", options={**opts, "offset": [0.25, 0.0, 0.5]})
    lo, hi = (np.asarray(b, np.float64) for b in np.asarray(cornell.bounds))
    cell = (hi - lo) / 3
    shift = np.asarray(moved.pos_world, np.float64) - np.asarray(base.pos_world, np.float64)
    np.testing.assert_allclose(
        shift, np.broadcast_to(cell * [0.25, 0.0, 0.5], shift.shape), rtol=1e-5, atol=1e-3
    )
    assert meta["config"]["offset"] == [0.25, 0.0, 0.5]


def _translated(scene, t):
    from probeplace.scene import transform_scene

    return transform_scene(scene, rotation=np.eye(3), translation=t)


def test_shift_keeps_the_grid_fixed_in_the_world(cornell):
    """The box-anchored grid moves with a translated scene; ``shift = −t`` keeps it where it was (exactly
    the untranslated lattice), i.e. the scene then moves relative to the grid (the stability study)."""
    lo, hi = scene_box(cornell)
    t = np.array([0.07, 0.0, -0.05]) * (hi - lo)
    opts = {"dims": (3, 3, 3), "inside": "keep"}
    base = np.asarray(_placed(cornell, method="grid", options=opts)[0].pos_world, np.float64)
    moved = _translated(cornell, t)
    follow = np.asarray(_placed(moved, method="grid", options=opts)[0].pos_world, np.float64)
    fixed, meta = _placed(moved, method="grid", options={**opts, "shift": (-t).tolist()})
    np.testing.assert_allclose(follow, base + t, atol=1e-4)
    np.testing.assert_allclose(np.asarray(fixed.pos_world, np.float64), base, atol=1e-4)
    assert meta["config"]["shift"] == pytest.approx((-t).tolist())
    with pytest.raises(ConfigError, match="shift"):
        _placed(cornell, method="grid", options={**opts, "shift": [float("nan"), 0.0, 0.0]})


def test_shift_keeps_the_lod_grid_on_its_world_lattice(cornell):
    """Every LOD-grid probe is a cell centre of the box at some level, so its coordinates are half-integer
    multiples of the finest cell from the box corner. With ``shift = −t`` in a scene translated by t they stay
    on the *untranslated* box's lattice; without it they follow the scene off that lattice. (Probes the
    valid-space step moved off a wall are off every lattice: ``valid_space.n_moved`` counts them.)"""
    lo, hi = scene_box(cornell)
    t = np.array([0.03, 0.0, 0.045]) * (hi - lo)
    base = (2, 2, 2)
    fine = (hi - lo) / (np.asarray(base) * 2**2)

    def on_lattice(pos):
        u = 2 * (np.asarray(pos, np.float64) - lo) / fine  # integers on the untranslated lattice
        return np.abs(u - np.round(u)).max(axis=1) < 1e-3

    moved = _translated(cornell, t)
    opts = {"base_divisions": base, "levels": 2}
    fixed, meta = _placed(moved, method="lod-grid", options={**opts, "shift": (-t).tolist()})
    follow, _ = _placed(moved, method="lod-grid", options=opts)
    n, n_moved = fixed.pos_world.shape[0], meta["valid_space"]["n_moved"]
    assert meta["config"]["levels"] == 2 and n > 8 and n_moved < n / 2
    assert on_lattice(fixed.pos_world).sum() == n - n_moved
    assert on_lattice(follow.pos_world).sum() == 0


@pytest.mark.slow  # several SDF-classified grids + coverage: ~15 s
def test_grid_budget_starts_from_the_nearest_grid(cornell):
    """Budget 40: exactly 40 probes, trimmed or filled from the lattice whose active count is nearest 40
    among the spacing search's lattices (spacing shrinking by 10 %)."""
    probes, meta = _placed(cornell, method="grid", budget=40)
    assert probes.capacity == 40
    from probeplace.placement import grid_dims

    lo, hi = scene_box(cornell)
    counts, spacing = {}, float(np.max(hi - lo))
    while not counts or max(counts.values()) <= 40:
        dims = tuple(grid_dims(lo, hi, spacing))
        counts.setdefault(dims, uniform_probe_grid(cornell, dims=dims, inside="disable").probes.n_active)
        spacing *= 0.9
    chosen = counts[tuple(meta["config"]["dims"])]
    assert abs(chosen - 40) == min(abs(c - 40) for c in counts.values())
    fit = meta["budget_fit"]
    assert fit["n_before"] - fit["n_trimmed"] + fit["n_filled"] == 40


def test_lod_grid_method(cornell):
    probes, meta = _placed(cornell, method="lod-grid", options={"base_divisions": (2, 2, 2), "levels": 2})
    g = lod_probe_grid(cornell, base_divisions=(2, 2, 2), sub_division_level=2)
    same = np.all(np.asarray(probes.pos_world) == g.positions, axis=1)  # all but the relocated probes
    assert (
        same.sum() == g.probe_count - meta["valid_space"]["n_moved"] and meta["valid_space"]["n_dropped"] == 0
    )
    assert sum(meta["lod_levels"]) == g.probe_count == meta["n_probes"]
    small, meta2 = _placed(
        cornell, method="lod-grid", budget=g.probe_count - 1, options={"base_divisions": (2, 2, 2)}
    )
    # the nearest level is level 2 (one probe too many): exactly one trimmed
    assert small.capacity == g.probe_count - 1 and meta2["config"]["levels"] == 2
    assert meta2["budget_fit"]["n_trimmed"] == 1


VARDIS_OPTS = {"dense_probes": 64, "n_eval": 64, "n_dirs": 64, "spp": 2, "max_depth": 3}


@pytest.mark.slow  # path-traced probe SH + coverage: ~40 s on 2 cores
def test_vardis_method_target_count(cornell):
    probes, meta = _placed(cornell, method="vardis", budget=20, options=VARDIS_OPTS)
    assert probes.capacity == 20 and probes.method == "vardis"
    lo, hi = scene_box(cornell)
    r = uniform_probe_grid(cornell, spacing=float(np.prod(hi - lo) / 64) ** (1 / 3), inside="disable")
    dense = np.asarray(r.probes.pos_world)[np.asarray(r.probes.active)]
    assert meta["n_dense"] == len(dense)
    # survivors are a subset of the dense set
    d = np.linalg.norm(np.asarray(probes.pos_world)[:, None] - dense[None], axis=-1).min(1)
    assert np.all(d == 0)
    h = meta["vardis_history"]
    assert h["count"][0] == len(dense) and h["count"][-1] == 20 and h["error"][0] == 0.0
    assert meta["refined"] is False and meta["timings"]["probe_values_s"] > 0
    # determinism: same seed → same dense values, evaluation points and removal order
    again, meta2 = _placed(cornell, method="vardis", budget=20, options=VARDIS_OPTS)
    np.testing.assert_array_equal(np.asarray(again.pos_world), np.asarray(probes.pos_world))
    assert meta2["vardis_history"] == h


def test_bad_options(cornell):
    with pytest.raises(ConfigError, match="unknown grid options"):
        _placed(cornell, method="grid", options={"spacing": 3})
    with pytest.raises(ConfigError, match="options apply"):
        _placed(cornell, method="skeleton", options={"dims": 3})
    with pytest.raises(ConfigError, match="method"):
        _placed(cornell, method="octree")


def test_cli_place_grid(tmp_path, capsys):
    out = tmp_path / "g.json"
    rc = main(
        [
            "place",
            "cornell_box",
            "--method",
            "grid",
            "-o",
            "dims=2,2,2",
            "-o",
            "inside=keep",
            "--out",
            str(out),
        ]
    )
    assert rc == 0
    data = json.loads(out.read_text())
    assert "8 probes" in capsys.readouterr().out
    assert "grid" in json.dumps(data)
    assert main(["place", "cornell_box", "--method", "grid", "-o", "dims"]) == 2  # KEY=VALUE required


@pytest.mark.slow  # refiner on the coverage objective: ~30 s
def test_baseline_refinement_never_lowers_coverage(cornell):
    _, base = _placed(cornell, method="grid", options={"dims": (2, 2, 2)})
    probes, meta = _placed(
        cornell, method="grid", options={"dims": (2, 2, 2)}, refiner="ascent", n_opt_samples=400
    )
    assert isinstance(meta["refined"], bool) and meta["coverage"] >= base["coverage"]
    assert probes.capacity == base["n_probes"] and "refine_s" in meta["timings"]
    assert meta["refine_converged"] == (meta["refine_status"] == "ok") and "refine_status" not in base


def test_place_returns_a_typed_result(cornell):
    """``place`` returns a frozen PlaceResult whose fields and ``metadata`` record agree."""
    import dataclasses

    from probeplace.placement import PlaceResult

    res = place(cornell, method="grid", options={"dims": (2, 2, 2)}, seed=1)
    assert isinstance(res, PlaceResult) and res.method == "grid" and res.request.seed == 1
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.coverage = 1.0
    meta = res.metadata
    assert meta["n_probes"] == res.n_probes == res.probes.capacity and meta["coverage"] == res.coverage
    assert res.refine_converged is None and meta["refined"] is False and "refine_status" not in meta
    assert res.target_reached is None and "target_reached" not in meta  # no automatic search
    json.dumps(meta)


def test_a_caster_object_decides_the_coverage(cornell):
    """``caster=`` takes a caster object as given: the exact JAX BVH's binary coverage of a grid equals
    Embree's (both exact casters of the same triangles; ties at grazing rays aside, so to 1e-3)."""
    from probeplace.geometry import make_caster

    opts = {"dims": (3, 3, 3), "inside": "disable"}
    by_embree = place(cornell, method="grid", options=opts, caster="embree")
    by_bvh = place(cornell, method="grid", options=opts, caster=make_caster(cornell, "bvh"))
    assert by_bvh.metadata["visibility"] == "BVHCaster"
    assert by_bvh.coverage == pytest.approx(by_embree.coverage, abs=1e-3)
