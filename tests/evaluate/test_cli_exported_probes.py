"""Issue 36 item 3: ``probeplace evaluate --probes`` scores a set exported to an engine file (glTF, USD,
probeplace's export JSON) as it scores the ProbeSet it came from. Oracle: the ProbeSet .json's own run —
the bake must receive bit-identical probes (positions, activity) from every file, so the deterministic
bake and evaluation that follow give identical metrics; and a file that cannot be read is refused in one
line before any slow work."""

from __future__ import annotations

import json

import numpy as np
import pytest

from probeplace.cli import main
from probeplace.export import export_probes, read_probes
from tests.test_cli_checks import probe_json, refused

# Cornell box positions (mm) that float32 does not hold exactly, and one inactive row.
POS = [[150.123456789, 250.5, 150.0], [400.0, 250.25, 399.987654321], [278.0, 300.0, 278.0]]


def _probes_reaching_the_bake(monkeypatch, tmp_path, probes_file):
    """Run ``evaluate`` on ``probes_file`` up to the bake; return the probes it would bake."""
    import probeplace.evaluate
    import probeplace.geometry
    import probeplace.probes

    seen = {}

    class Stop(Exception):
        pass

    def bake(scene, probes, *, caster, radiance_fn, key, config):
        seen["probes"] = probes
        raise Stop

    monkeypatch.setattr(probeplace.geometry, "make_caster", lambda *a, **k: None)
    monkeypatch.setattr(probeplace.probes, "path_traced_radiance", lambda *a, **k: lambda o, d, k: None)
    monkeypatch.setattr(probeplace.probes, "choose_bake_spp", _no_choice)
    monkeypatch.setattr(probeplace.probes, "bake_probes", bake)
    monkeypatch.setattr(
        probeplace.evaluate, "evaluate", lambda *a, **k: pytest.fail("evaluated before baking")
    )
    argv = ["evaluate", "--scene", "cornell_box", "--probes", str(probes_file), "--out", str(tmp_path / "ev")]
    with pytest.raises(Stop):
        main(argv)
    p = seen["probes"]
    return np.asarray(p.pos_world), np.asarray(p.active)


class _Fixed:
    chosen_by = "fixed"

    @staticmethod
    def radiance_fn(fn):
        return fn


def _no_choice(*a, **k):
    return _Fixed()


@pytest.mark.parametrize("suffix", [".glb", ".gltf", ".usda", ".export.json"])
def test_an_exported_set_reaches_the_bake_as_the_probe_set_it_came_from(monkeypatch, tmp_path, suffix):
    source = probe_json(tmp_path / "placed.json", pos=POS, active=[True, False, True])
    doc = json.loads(source.read_text())
    doc["metadata"] = {"scene": "cornell_box"}  # as `probeplace place` records it
    source.write_text(json.dumps(doc))
    fmt = {".glb": "gltf", ".gltf": "gltf", ".usda": "usd", ".export.json": "json"}[suffix]
    exported = tmp_path / f"probes{suffix}"
    export_probes(read_probes(source), fmt, exported)
    want = _probes_reaching_the_bake(monkeypatch, tmp_path, source)
    got = _probes_reaching_the_bake(monkeypatch, tmp_path, exported)
    np.testing.assert_array_equal(got[0], want[0])  # bit-identical positions, inactive row included
    np.testing.assert_array_equal(got[1], want[1])
    assert want[1].sum() == 2 and want[0].dtype == np.float32


def test_an_exported_set_of_another_scene_is_refused(tmp_path, capsys, no_slow_work):
    source = probe_json(tmp_path / "placed.json")
    doc = json.loads(source.read_text())
    doc["metadata"] = {"scene": "crytek_sponza"}
    source.write_text(json.dumps(doc))
    export_probes(read_probes(source), "gltf", tmp_path / "p.glb")
    argv = ["evaluate", "--scene", "cornell_box", "--probes", str(tmp_path / "p.glb"), "--out", str(tmp_path)]
    refused(argv, capsys, "--probes", "crytek_sponza")


@pytest.mark.parametrize(
    ("name", "content", "needle"),
    [
        ("cut.glb", b"glTF\x02\x00\x00\x00", "cut.glb: truncated GLB header"),
        (
            "other.gltf",
            json.dumps({"asset": {"version": "2.0"}, "nodes": [{}]}).encode(),
            "no probeplace probe",
        ),
        ("probes.txt", b"x", "--probes must be a ProbeSet .json, a baked .npz or an exported set"),
    ],
    ids=["cut-glb", "gltf-without-probes", "unknown-suffix"],
)
def test_unreadable_exported_sets_are_refused_in_one_line(
    tmp_path, capsys, no_slow_work, name, content, needle
):
    path = tmp_path / name
    path.write_bytes(content)
    argv = ["evaluate", "--scene", "cornell_box", "--probes", str(path), "--out", str(tmp_path / "ev")]
    refused(argv, capsys, needle)
