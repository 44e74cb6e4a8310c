"""Write → read back → compare, per format with an importer; plus the JSON Schema and bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from probeplace.export import (
    ExportError,
    ExportProbes,
    export_probes,
    import_probes,
    read_lod_grid,
    read_probes,
    schema,
)

from ._fixture import asymmetric_probes
from ._schema_check import check_schema


def assert_same(a: ExportProbes, b: ExportProbes, *, sh: bool = True) -> None:
    """Bit-exact equality of everything a probe set carries."""
    np.testing.assert_array_equal(a.positions, b.positions)
    assert a.positions.dtype == b.positions.dtype == np.float32
    np.testing.assert_array_equal(a.active, b.active)
    assert (a.method, a.units_m, a.metadata) == (b.method, b.units_m, b.metadata)
    np.testing.assert_array_equal(a.inside, b.inside)
    if sh:
        np.testing.assert_array_equal(a.sh, b.sh)


@pytest.mark.parametrize("name", ["p.json", "p.gltf", "p.glb", "p.usda", "p.usdc"])
def test_round_trip_is_lossless(tmp_path, name):
    src = asymmetric_probes()
    fmt = {"json": "json", "gltf": "gltf", "glb": "gltf", "usda": "usd", "usdc": "usd"}[name.split(".")[1]]
    export_probes(src, fmt, tmp_path / name)
    assert_same(src, import_probes(tmp_path / name))


def test_round_trip_without_sh_keeps_none(tmp_path):
    src = asymmetric_probes(with_sh=False)
    for name, fmt in (("a.json", "json"), ("a.gltf", "gltf"), ("a.usda", "usd")):
        export_probes(src, fmt, tmp_path / name)
        assert import_probes(tmp_path / name).sh is None


def test_threev8_round_trip_returns_the_active_probes(tmp_path):
    src = asymmetric_probes(with_maps=True)
    export_probes(src, "threev8", tmp_path / "g.lodprobes")
    back = import_probes(tmp_path / "g.lodprobes")
    act = src.active_only()
    assert_same(act, back)


def test_threev8_index_finds_every_probe_in_its_own_cell(tmp_path):
    """Oracle: Yang 2023's traversal (get_probe_idx) from a probe's position returns that probe, every
    probe is one leaf, and inner entries point at 8-entry child blocks inside the array."""
    src = asymmetric_probes()
    export_probes(src, "threev8", tmp_path / "g.lodprobes")
    grid = read_lod_grid(tmp_path / "g.lodprobes")
    act = src.active_only()
    for i, p in enumerate(act.positions):
        assert grid.probe_index_at(p) == i
    leaves = grid.index[grid.index < grid.probe_count]
    assert sorted(leaves.tolist()) == list(range(grid.probe_count))  # each probe exactly one leaf
    inner = grid.index[grid.index >= grid.probe_count] - grid.probe_count
    base = int(np.prod(grid.base_divisions))
    assert len(grid.index) == base + 8 * len(inner)
    assert sorted(inner.tolist()) == list(range(len(inner)))
    # levels: a probe of level l sits in a cell of size base/2^l containing it
    size = (grid.coverage_max - grid.coverage_min).astype(np.float64)
    for i in range(grid.probe_count):
        lvl = int(grid.probe_data[i, 0, 3])
        cell = size / (grid.base_divisions << lvl)
        assert grid.probe_index_at(grid.probe_data[i, 0, :3]) == i
        assert np.all(cell > 0)
    # fillers copy the SH of the nearest real probe
    n = act.n
    for i in range(n, grid.probe_count):
        d = np.linalg.norm(act.positions - grid.probe_data[i, 0, :3], axis=1)
        np.testing.assert_array_equal(grid.probe_data[i, 1:, :3], act.sh[np.argmin(d)])


def test_threev8_visibility_holds_normalised_moments(tmp_path):
    src = asymmetric_probes(with_maps=True)
    export_probes(src, "threev8", tmp_path / "g.lodprobes", vis_res=4)  # == bake res: no resampling
    grid = read_lod_grid(tmp_path / "g.lodprobes")
    side = json.loads((tmp_path / "g.lodprobes.json").read_text())
    act = src.active_only()
    t = grid.vis_res + 2
    for k in range(act.n):
        r, c = divmod(k, grid.pack_size)
        tile = grid.visibility[r * t : (r + 1) * t, c * t : (c + 1) * t].astype(np.float64) / 65535.0
        m = act.maps.moments[k].astype(np.float64)
        expect_mean = np.clip(m[..., 0] / side["visibility_max_distance"], 0, 1)
        np.testing.assert_allclose(tile[..., 0], expect_mean, atol=0.5 / 65535 + 1e-7)  # 16-bit rounding


def test_json_validates_against_the_shipped_schema(tmp_path):
    export_probes(asymmetric_probes(), "json", tmp_path / "p.json")
    doc = json.loads((tmp_path / "p.json").read_text())
    check_schema(doc, schema())
    bad = dict(doc, handedness="left")
    with pytest.raises(AssertionError):
        check_schema(bad, schema())
    bad = dict(doc, extra_field=1)
    with pytest.raises(AssertionError):
        check_schema(bad, schema())


@pytest.mark.parametrize(
    "mutate, msg",
    [
        (lambda d: d.update(format="nope"), "unknown format"),
        (lambda d: d.update(count=99), "count says"),
        (lambda d: d.update(up_axis="+Z"), "up_axis"),
        (lambda d: d.update(positions=[[0, 0]]), "bad probe arrays"),
    ],
)
def test_bad_json_is_a_clear_error(tmp_path, mutate, msg):
    export_probes(asymmetric_probes(), "json", tmp_path / "p.json")
    doc = json.loads((tmp_path / "p.json").read_text())
    mutate(doc)
    (tmp_path / "p.json").write_text(json.dumps(doc))
    with pytest.raises(ExportError, match=msg):
        import_probes(tmp_path / "p.json")


def test_bad_inputs_are_clear_errors(tmp_path):
    with pytest.raises(ExportError, match="not found"):
        read_probes(tmp_path / "missing.json")
    (tmp_path / "x.glb").write_bytes(b"glTF\x02\x00\x00\x00")
    with pytest.raises(ExportError, match="GLB"):
        import_probes(tmp_path / "x.glb")
    (tmp_path / "x.lodprobes").write_bytes(b"\x00" * 10)
    with pytest.raises(ExportError, match="too short"):
        import_probes(tmp_path / "x.lodprobes")
    with pytest.raises(ExportError, match="unknown export format"):
        export_probes(asymmetric_probes(), "fbx", tmp_path / "x.fbx")
    with pytest.raises(ExportError, match="no importer"):
        import_probes(tmp_path / "x.glb", fmt="unity")
    with pytest.raises(ExportError, match="finite"):
        ExportProbes(positions=[[0, np.nan, 0]], active=[True])
    with pytest.raises(ExportError, match="DDGI textures need baked probes"):
        export_probes(asymmetric_probes(), "ddgi", tmp_path / "d.json")
    dup = ExportProbes(positions=[[1, 1, 1], [1, 1, 1]], active=[True, True])
    with pytest.raises(ExportError, match="too close"):
        export_probes(dup, "threev8", tmp_path / "d.lodprobes")
