"""The `place` subcommand."""

import json

import pytest

from probeplace.cli import main


def test_version(capsys):
    from probeplace import __version__

    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"probeplace {__version__}"


def test_place_bad_budget(capsys):
    assert main(["place", "cornell_box", "--budget", "zero"]) == 2
    assert "budget" in capsys.readouterr().err


@pytest.mark.slow
def test_place_writes_probe_set_and_png(tmp_path):
    from probeplace._core import load_probe_set

    out = tmp_path / "p.json"
    assert main(["place", "cornell_box", "--out", str(out)]) == 0
    probes, meta = load_probe_set(out)
    assert meta["metadata"]["coverage"] == 1.0
    assert meta["metadata"]["n_probes"] == probes.capacity <= 8
    assert (tmp_path / "p.png").stat().st_size > 1000
    json.dumps(meta)


def test_place_writes_each_probe_s_part_in_the_coverage_for_the_viewer(tmp_path):
    """Beside the probe set, ``<stem>.coverage.npz`` (``placement.CoverageDetail``): its coverage is the
    record's, its counts add up to the coverable samples, and ``probeplace view``'s model reads it for the
    bare probes file (coverage colours, uncovered points)."""
    import numpy as np

    from probeplace._core import load_probe_set
    from probeplace.view import load_view_model, resolve_input

    out = tmp_path / "p.json"
    assert main(["place", "cornell_box", "--method", "grid", "--budget", "8", "--out", str(out)]) == 0
    _, meta = load_probe_set(out)
    with np.load(tmp_path / "p.coverage.npz") as z:
        assert str(z["format"]) == "probeplace.CoverageDetail/1"
        assert float(z["coverage"]) == meta["metadata"]["coverage"]
        assert z["seen"].shape == (8,) and (z["unique"] <= z["seen"]).all()
        assert z["unique"].sum() + int(z["n_multiple"]) + len(z["uncovered"]) == int(z["n_coverable"])
    model = load_view_model(resolve_input(out))
    assert model.coverage is not None and model.coverage.path == tmp_path / "p.coverage.npz"
    np.testing.assert_array_equal(
        model.values("coverage: samples it sees"), np.load(tmp_path / "p.coverage.npz")["seen"]
    )


def test_place_memory_budget_and_height_band(tmp_path):
    """``--memory-budget`` becomes the count its bake settings allow; ``--height-band`` keeps every probe
    in the band above the floor; both reach the record."""
    from probeplace._core import load_probe_set
    from probeplace.probes import BakeConfig, probe_bytes
    from probeplace.scene import load_scene

    out = tmp_path / "p.json"
    argv = ["place", "cornell_box", "--method", "grid", "--memory-budget", "2MiB", "--radiance-res", "32"]
    assert main([*argv, "--height-band", "100,300", "--out", str(out)]) == 0
    probes, meta = load_probe_set(out)
    want = 2**20 * 2 // probe_bytes(load_scene("cornell_box"), BakeConfig(radiance_res=32))
    y = probes.pos_world[:, 1]
    assert probes.capacity == meta["metadata"]["n_probes"] == want
    assert float(y.min()) >= 100.0 and float(y.max()) <= 300.0  # the floor is at y = 0
    assert meta["metadata"]["valid_space"]["region"]["height"] == [100.0, 300.0]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--memory-budget", "lots"], "memory budget"),
        (["--memory-budget", "1MiB", "--budget", "4"], "not both"),
        (["--height-band", "1"], "--height-band must be 2"),
        (["--clearance", "-1"], "clearance"),
    ],
)
def test_place_bad_budget_and_space_options_are_one_line(argv, message, capsys):
    assert main(["place", "cornell_box", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_place_coverage_rule_reaches_the_fitness(tmp_path):
    """``--coverage views`` is the fitness's rule (recorded with the search problem): on the Cornell box,
    whose one view camera sees less than the probes can reach, the coverable area share is smaller and the
    automatic budget needs no more probes."""
    from probeplace._core import load_probe_set

    meta = {}
    for rule in ("reachable", "views"):
        out = tmp_path / f"{rule}.json"
        assert main(["place", "cornell_box", "--coverage", rule, "--out", str(out)]) == 0
        meta[rule] = load_probe_set(out)[1]["metadata"]
        assert meta[rule]["config"]["coverage"] == rule
    share = {k: m["coverable_area_share"] for k, m in meta.items()}
    assert 0 < share["views"] < share["reachable"]
    assert meta["views"]["n_probes"] <= meta["reachable"]["n_probes"]


def test_place_bad_coverage_rule(capsys):
    with pytest.raises(SystemExit) as e:
        main(["place", "cornell_box", "--coverage", "everything"])
    assert e.value.code == 2
    assert "--coverage" in capsys.readouterr().err
