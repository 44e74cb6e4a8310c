"""Issue 31: inputs that do not fit the scene are refused (or warned about) before any bake or render.

* probes of another scene: a ProbeSet recording another scene, or lying far outside the scene's bounds;
* a view camera inside solid geometry (refused, naming the sidecar, the camera and its position);
* a light that reaches none of the surface points the views see (a warning with the figure).

The command-line cases run ``probeplace evaluate`` in-process under ``no_slow_work`` (caster build, bake
and evaluation raise if reached); the checks' own Embree caster is built directly, not by
``geometry.make_caster``, which is what that fixture blocks.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import pytest

from probeplace._core import ConfigError
from probeplace.cli import main
from probeplace.evaluate._scene_checks import host_caster, light_reach, warn_unreached_lights
from probeplace.probes._bake import PROBES_OUTSIDE_SHARE, check_probes_in_scene
from probeplace.probes._inside import points_in_solid
from probeplace.scene import build_scene, load_scene, make_materials
from probeplace.scene._primitives import box
from tests.scene.sidecar_util import LAMP, write_room_obj

CORNELL = np.array([556.0, 548.8, 559.2])
LO, HI = np.zeros(3), np.array([4.0, 3.0, 5.0])


def cornell_grid() -> list[list[float]]:
    """96 probes on a 6×4×4 grid inside the Cornell box (mm): a set made for ``cornell_box``."""
    g = np.stack(np.meshgrid(*[np.linspace(0.1, 0.9, n) for n in (6, 4, 4)], indexing="ij"), -1)
    return (g.reshape(-1, 3) * CORNELL).tolist()


def probe_file(path: Path, pos, scene: str | None = None) -> Path:
    doc = {"format": "probeplace.ProbeSet/1", "method": "grid", "positions": pos, "active": [True] * len(pos)}
    if scene is not None:
        doc["metadata"] = {"scene": scene}
    path.write_text(json.dumps(doc))
    return path


def refused(argv: list[str], capsys) -> str:
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("probeplace: error: "), err
    return lines[0]


def evaluate_argv(tmp_path: Path, scene: str, probes: Path, *extra: str) -> list[str]:
    return ["evaluate", "--scene", scene, "--probes", str(probes), "--out", str(tmp_path / "ev"),
            "--width", "8", "--height", "8", *extra]  # fmt: skip


# ------------------------------------------------------------------------------ probes of another scene
def test_cornell_probes_recorded_as_cornell_are_refused_on_rooms(tmp_path, capsys, no_slow_work):
    probes = probe_file(tmp_path / "p.json", cornell_grid(), scene="cornell_box")
    line = refused(evaluate_argv(tmp_path, "rooms", probes), capsys)
    assert "placed in scene 'cornell_box' but are evaluated in 'rooms'" in line
    assert "--scene cornell_box" in line and str(probes) in line
    assert not (tmp_path / "ev").exists()


def test_cornell_probes_without_a_record_are_refused_by_the_bounds(tmp_path, capsys, no_slow_work):
    """Millimetre probes in a metre scene: all 96 lie farther out than the scene is large."""
    probes = probe_file(tmp_path / "p.json", cornell_grid())
    line = refused(evaluate_argv(tmp_path, "rooms", probes), capsys)
    assert "96 of 96 probes lie outside rooms's bounds" in line and "place probes in rooms" in line
    assert not (tmp_path / "ev").exists()


def test_probes_100_m_outside_are_refused(tmp_path, capsys, no_slow_work):
    rooms = load_scene("rooms")
    lo, hi = (np.asarray(b, np.float64) for b in rooms.bounds)
    pos = (0.5 * (lo + hi) + [100.0, 0.0, 0.0] + np.arange(8)[:, None] * 0.1).tolist()
    line = refused(evaluate_argv(tmp_path, "rooms", probe_file(tmp_path / "p.json", pos)), capsys)
    assert "8 of 8 probes lie outside rooms's bounds" in line


@pytest.fixture(scope="module")
def cornell_npz(tmp_path_factory) -> Path:
    """Probes baked in ``cornell_box`` (module scope: built before ``no_slow_work`` blocks baking)."""
    from probeplace.probes import save_probes
    from tests.reliability.catalogue import _baked

    return save_probes(tmp_path_factory.mktemp("npz") / "b.npz", _baked())


def test_baked_npz_of_another_scene_is_refused_before_the_caster(tmp_path, capsys, cornell_npz, no_slow_work):
    """The .npz check (recorded bake scene) now runs before any caster is built."""
    line = refused(evaluate_argv(tmp_path, "rooms", cornell_npz), capsys)
    assert "baked in scene 'cornell_box' but are evaluated in 'rooms'" in line


@pytest.mark.parametrize(
    ("recorded", "given"),
    [("cornell_box", "cornell_box"), ("/data/scenes/room.obj", "room"), ("room", "other/room.obj")],
)
def test_the_recorded_scene_matches_by_the_name_it_loads_under(tmp_path, recorded, given):
    from probeplace.cli._evaluate import _check_recorded_scene

    _check_recorded_scene({"metadata": {"scene": recorded}}, tmp_path / "p.json", given)  # no error
    _check_recorded_scene({"metadata": {}}, tmp_path / "p.json", given)  # nothing recorded: nothing to check


def test_bounds_check_margin_and_share():
    """Oracle: the rule as stated (PROBES_OUTSIDE_MARGIN = one scene size, more than a tenth of the set)."""
    size = float(np.max(HI - LO))
    inside = np.tile([[2.0, 1.5, 2.5]], (20, 1))
    near = inside.copy()
    near[:] = [2.0, 1.5, 5.0 + 0.99 * size]  # all just inside the margin: a warning's business, not ours
    check_probes_in_scene(near, LO, HI, "t")
    k = int(PROBES_OUTSIDE_SHARE * 20)  # 2 of 20 far out: not more than a tenth
    few = inside.copy()
    few[:k] = [2.0, 1.5, 5.0 + 1.01 * size]
    check_probes_in_scene(few, LO, HI, "t")
    few[: k + 1] = [2.0, 1.5, 5.0 + 1.01 * size]
    with pytest.raises(ConfigError, match=rf"^t: {k + 1} of 20 probes lie outside room's bounds"):
        check_probes_in_scene(few, LO, HI, "t", scene="room")


def test_bake_refuses_probes_of_another_scene_before_any_ray():
    import jax

    from probeplace._core import ProbeSet
    from probeplace.probes import BakeConfig, bake_probes
    from tests.reliability.catalogue import const_radiance

    class NoRays:
        def __getattr__(self, name):
            raise AssertionError("the bake cast a ray before refusing")

    room = build_scene("room", *box(LO, HI), np.zeros(12, int), make_materials(["w"], np.full((1, 3), 0.5)))
    pos = np.asarray(cornell_grid()[:4], np.float32)
    probes = ProbeSet(pos_world=jax.numpy.asarray(pos), active=jax.numpy.ones(4, bool))
    with pytest.raises(ConfigError, match=r"^bake: 4 of 4 probes lie outside room's bounds"):
        bake_probes(room, probes, caster=NoRays(), radiance_fn=const_radiance, key=jax.random.key(0),
                    config=BakeConfig(radiance_res=16, progress=False))  # fmt: skip


# ------------------------------------------------------------------------------ cameras inside solids
def _solids_scene():
    """An inward-facing room 4×3×5 (seen from inside as front faces) holding a closed outward block."""
    rv, rf = box(LO, HI)
    bv, bf = box([1.0, 0.5, 1.0], [2.0, 1.5, 2.0])  # off the floor: no face coplanar with the room's
    v = np.concatenate([rv, bv])
    f = np.concatenate([rf[:, ::-1], bf + len(rv)])
    return build_scene("solids", v, f, np.zeros(len(f), int), make_materials(["w"], np.full((1, 3), 0.5)))


def test_points_in_solid_oracle():
    scene = _solids_scene()
    caster = host_caster(scene)
    pts = np.array([[1.5, 1.0, 1.5], [3.0, 1.5, 4.0], [1.5, 2.0, 1.5]])  # in the block, in the room, above it
    inside, share = points_in_solid(caster, scene, pts)
    assert inside.tolist() == [True, False, False]
    assert share[0] == 1.0 and share[1] == 0.0
    # winding alone does not decide: a point outside the room's inward shell sees only back faces, but
    # rays escape past it, so it is not inside a solid
    out, share = points_in_solid(caster, scene, np.array([[2.0, 1.5, -3.0]]))
    assert not out[0] and share[0] > 0


@pytest.fixture
def room(tmp_path) -> Path:
    """The sidecar tests' room (closed boxes, a window in the +Z wall, a lamp box on the floor)."""
    write_room_obj(tmp_path)
    probe_file(tmp_path / "p.json", [[1.0, 1.5, 1.0], [3.0, 1.5, 4.0]])
    return tmp_path


def _sidecar(room: Path, text: str) -> None:
    (room / "room.probeplace.yaml").write_text(text)


LAMP_CENTRE = [(a + b) / 2 for a, b in zip(*LAMP, strict=True)]


def test_sidecar_camera_inside_a_solid_is_refused(room, capsys, no_slow_work):
    x, y, z = LAMP_CENTRE
    _sidecar(room, "sun: {azimuth: 90, elevation: 35}\nsky: daylight\ncameras:\n"
             "  door: {position: [2, 1.5, 0.5], look_at: [2, 1.2, 4]}\n"
             f"  lamp: {{position: [{x}, {y}, {z}], look_at: [2, 0.2, 4]}}\n")  # fmt: skip
    line = refused(evaluate_argv(room, str(room / "room.obj"), room / "p.json", "--view", "door"), capsys)
    assert line.startswith(
        f"probeplace: error: room.probeplace.yaml: cameras.lamp: position [{x:g}, {y:g}, {z:g}] is inside "
        "solid geometry"
    ), line
    assert "move position into free space" in line
    assert not (room / "ev").exists()


def test_cli_camera_inside_a_solid_is_refused(capsys, tmp_path, no_slow_work):
    """``--camera`` on a built-in: the message names the overrides. (Inside the Cornell box's tall block.)"""
    probes = probe_file(tmp_path / "p.json", cornell_grid()[:4])
    argv = evaluate_argv(tmp_path, "cornell_box", probes, "--camera", "name=c,pos=370,100,350,look_at=0,0,0")
    line = refused(argv, capsys)
    want = "probeplace: error: overrides: cameras.c: position [370, 100, 350] is inside solid geometry"
    assert line.startswith(want), line


# ------------------------------------------------------------------------------ lights that reach no view
def test_sun_below_the_horizon_of_a_closed_room_is_warned_about(room, caplog, no_slow_work):
    """The warning comes before the slow work (which no_slow_work turns into an AssertionError)."""
    _sidecar(room, "sun: {azimuth: 90, elevation: -20}\ncameras:\n"
             "  door: {position: [2, 1.5, 0.5], look_at: [2, 1.2, 4]}\n")  # fmt: skip
    with caplog.at_level(logging.WARNING, logger="probeplace"), pytest.raises(AssertionError, match="slow"):
        main(evaluate_argv(room, str(room / "room.obj"), room / "p.json"))
    msgs = [r.getMessage() for r in caplog.records if "reaches 0 of" in r.getMessage()]
    assert len(msgs) == 1, caplog.text
    assert "the sun (elevation -20°, below the horizon)" in msgs[0]
    assert "raise sun.elevation" in msgs[0] and "room.probeplace.yaml" in msgs[0]


def test_sun_through_the_window_reaches_the_views(room):
    """Counter-case: a sun low in the +Z sky shines through the window onto the floor the door view sees."""
    _sidecar(room, "sun: {azimuth: 90, elevation: 35}\ncameras:\n"
             "  door: {position: [2, 1.5, 0.5], look_at: [2, 0.6, 4]}\n")  # fmt: skip
    scene = load_scene(room / "room.obj")
    n, reach = light_reach(scene, host_caster(scene))
    assert n > 500 and 0 < reach["sun"] < n


@pytest.mark.parametrize("name", ["cornell_box", "rooms", "temple", "courtyard"])
def test_builtin_scenes_pass_both_checks(name, caplog):
    """No false alarm on the built-ins: no camera in a solid, every light reaches what the views see."""
    from probeplace.evaluate._scene_checks import check_view_cameras

    scene = load_scene(name)
    caster = host_caster(scene)
    check_view_cameras(scene, caster)
    with caplog.at_level(logging.WARNING, logger="probeplace"):
        reach = warn_unreached_lights(scene, caster)
    assert reach and all(v > 0 for v in reach.values()), reach
    assert "reaches 0 of" not in caplog.text
