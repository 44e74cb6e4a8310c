"""Issue 31: ``probeplace scenes -v NAME`` prints what a scene's sidecar resolved to — units, bounds,
triangles, sun, sky, emitters, cameras — checked here against the sidecar's own values and the room's
geometry as written."""

from __future__ import annotations

import re

import numpy as np
import pytest

from probeplace.cli import main
from tests.scene.sidecar_util import room_boxes, write_room_obj

SIDECAR = """\
units: cm
sun: {azimuth: 120, elevation: 35, irradiance: [8, 7, 6]}
sky: [0.1, 0.2, 0.3]
emitters:
  lamp: {strength: 5, color: [1, 0.5, 0.25]}
cameras:
  door: {position: [2.0, 1.6, 0.5], look_at: [2.0, 0.8, 3.0], fov: 50}
"""


def _vectors(text: str) -> list[list[float]]:
    return [[float(x) for x in g.split(",")] for g in re.findall(r"\(([-0-9.e, ]+)\)", text)]


def _number(after: str, text: str) -> float:
    return float(re.search(rf"{after} ([-0-9.e]+)", text).group(1))


def _show(capsys, *argv: str) -> dict[str, list[str]]:
    assert main(["scenes", *argv]) == 0
    out: dict[str, list[str]] = {}
    for line in capsys.readouterr().out.splitlines():
        key, _, text = line.partition(" ")
        out.setdefault(key, []).append(text.strip())
    return out


def test_scenes_v_prints_the_resolved_sidecar(tmp_path, capsys):
    room = write_room_obj(tmp_path)
    (tmp_path / "room.probeplace.yaml").write_text(SIDECAR)
    out = _show(capsys, "-v", str(room))

    assert out["scene"] == [f"room ({room})"] and out["config"] == ["room.probeplace.yaml"]
    assert out["units"] == ["0.01 m per unit"]
    boxes = [b for bs in room_boxes().values() for b in bs]
    lo, hi = np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)
    b_lo, b_hi, _ = _vectors(out["bounds"][0])
    np.testing.assert_allclose(b_lo, lo, atol=1e-6)
    np.testing.assert_allclose(b_hi, hi, atol=1e-6)
    assert out["triangles"] == [str(12 * len(boxes))]  # a closed box is 12 triangles

    (sun,) = out["sun"]
    assert _number("azimuth", sun) == pytest.approx(120.0, abs=1e-4)
    assert _number("elevation", sun) == pytest.approx(35.0, abs=1e-4)
    direction, irradiance, _ = _vectors(sun)
    az, el = np.deg2rad(120.0), np.deg2rad(35.0)
    expected = [np.cos(el) * np.cos(az), np.sin(el), np.cos(el) * np.sin(az)]  # from +X toward +Z, +Y up
    np.testing.assert_allclose(direction, expected, atol=1e-5)
    np.testing.assert_allclose(irradiance, [8, 7, 6], rtol=1e-5)
    assert "angular diameter 0.53" in sun  # the real sun's size, the default

    # The sky, emitter and camera values below are the sidecar's decimals stored as float32 (≤ 6e-8
    # relative) and printed to 6 significant digits, which round them back; no arithmetic touches them, so
    # no instruction set can move them: 1e-6 is the print's own precision.
    np.testing.assert_allclose(_vectors(out["sky"][0])[0], [0.1, 0.2, 0.3], rtol=1e-6)
    (lamp,) = out["emitter"]
    assert lamp.startswith("lamp: ") and lamp.endswith(", 12 triangles")
    np.testing.assert_allclose(_vectors(lamp)[0], [5.0, 2.5, 1.25], rtol=1e-6)

    door = next(c for c in out["camera"] if c.startswith("door: "))
    position, look_at, up = _vectors(door)
    np.testing.assert_allclose(position, [2.0, 1.6, 0.5], rtol=1e-6)
    np.testing.assert_allclose(look_at, [2.0, 0.8, 3.0], rtol=1e-6)
    assert up == [0.0, 1.0, 0.0] and door.endswith("fov 50°")


def test_scenes_name_takes_the_sidecar_overrides(capsys):
    """``--sun`` / ``--sky`` win over a built-in's own light, as for ``place``; without a NAME they are
    refused in one line."""
    out = _show(capsys, "cornell_box", "--sun", "az=10,el=20", "--sky", "none")
    assert out["config"] == ["overrides"] and out["sky"] == ["none"]
    assert _number("azimuth", out["sun"][0]) == pytest.approx(10.0, abs=1e-4)
    assert _number("elevation", out["sun"][0]) == pytest.approx(20.0, abs=1e-4)
    assert out["emitter"][0].startswith("light: radiance (17, 12, 4), 2 triangles")
    assert main(["scenes", "--sun", "az=10,el=20"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "probeplace: error: --sun, --sky and --camera need a scene: probeplace scenes NAME --sun ..."
    ]
