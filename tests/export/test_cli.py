"""``probeplace export <probes> --format <name> --out <path>`` end to end."""

from __future__ import annotations

import json

import numpy as np
import pytest

from probeplace.cli import main
from probeplace.export import import_probes, read_probes

from ._fixture import ACTIVE, INSIDE, POSITIONS, UNITS_M, write_baked_npz


@pytest.fixture
def probe_set_file(tmp_path):
    """A ProbeSet file exactly as ``_core.save_probe_set`` writes it (format probeplace.ProbeSet/1)."""
    import jax.numpy as jnp

    from probeplace import ProbeSet
    from probeplace._core import save_probe_set

    ps = ProbeSet(pos_world=jnp.asarray(POSITIONS), active=jnp.asarray(ACTIVE), method="grid")
    return save_probe_set(tmp_path / "set.json", ps, units_m=UNITS_M, metadata={"seed": 3})


@pytest.fixture
def npz_file(tmp_path):
    path = tmp_path / "baked.npz"
    write_baked_npz(path)
    return path


@pytest.mark.parametrize(
    "fmt, name", [("json", "o.json"), ("gltf", "o.glb"), ("threev8", "o.lodprobes"), ("usd", "o.usda")]
)
def test_probe_set_file_round_trips_through_the_cli(tmp_path, probe_set_file, fmt, name, capsys):
    assert main(["export", str(probe_set_file), "--format", fmt, "--out", str(tmp_path / name)]) == 0
    assert str(tmp_path / name) in capsys.readouterr().out
    back = import_probes(tmp_path / name)
    src = read_probes(probe_set_file)
    if fmt == "threev8":
        src = src.active_only()
    np.testing.assert_array_equal(back.positions, src.positions)
    np.testing.assert_array_equal(back.active, src.active)
    assert (back.method, back.units_m, back.metadata) == ("grid", UNITS_M, {"seed": 3})


def test_npz_with_probe_set_gives_sh_and_textures(tmp_path, npz_file, probe_set_file):
    out = tmp_path / "o.json"
    args = [
        "export",
        str(npz_file),
        "--probe-set",
        str(probe_set_file),
        "--format",
        "json",
        "--out",
        str(out),
    ]
    assert main(args) == 0
    doc = json.loads(out.read_text())
    assert doc["method"] == "grid" and doc["units_m"] == UNITS_M
    assert np.asarray(doc["sh"]["coefficients"]).shape == (6, 9, 3)
    assert doc["inside"] == INSIDE.tolist()
    assert main(["export", str(npz_file), "--format", "ddgi", "--out", str(tmp_path / "d.json")]) == 0
    assert (tmp_path / "d.irradiance.exr").is_file()


def test_errors_are_one_line_and_exit_2(tmp_path, capsys):
    assert main(["export", str(tmp_path / "none.json"), "--format", "json", "--out", "x.json"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("probeplace: error:") and "not found" in err
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    assert main(["export", str(tmp_path / "bad.npz"), "--format", "json", "--out", "x.json"]) == 2
