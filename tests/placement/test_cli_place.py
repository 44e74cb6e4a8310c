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
