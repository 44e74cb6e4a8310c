"""The runner on a scene of one's own (issue 19): ``scene.overrides`` carries the sidecar keys (sun, sky,
cameras, ...) for a file scene, checked like a sidecar; ``check_scenes`` loads each scene of a sweep once
and refuses a scene without light for a bake, or an ``eval.view`` it lacks, before any run starts; and
``run`` from Python refuses a results folder it cannot write before loading the scene."""

from __future__ import annotations

import numpy as np
import pytest

from probeplace._core import ConfigError, SceneError
from probeplace.experiment import check_scenes, load_experiment_scene, run, run_name, to_config
from probeplace.scene import DAYLIGHT_SKY_RADIANCE, sun_direction
from tests.scene.sidecar_util import write_room_obj

F32_EPS = float(np.finfo(np.float32).eps)
DOOR = {"position": [2.0, 1.6, 0.5], "look_at": [2.0, 0.8, 3.0], "fov": 60}
LIGHT = {"sun": {"azimuth": 90, "elevation": 35, "irradiance": 8}, "sky": "daylight"}


@pytest.fixture
def room(tmp_path):
    """The sidecar tests' room: a file with no light and no cameras (and no sidecar)."""
    return write_room_obj(tmp_path)


def _cfg(room, overrides=None, **groups):
    return to_config({"scene": {"name": str(room), "overrides": overrides or {}}, **groups})


def test_scene_overrides_light_and_frame_a_file_scene(room):
    cfg = _cfg(room, {**LIGHT, "cameras": {"door": DOOR}}, eval={"view": "door"})
    scene = load_experiment_scene(cfg.scene, require_light=True)
    assert scene.has_light and [v.name for v in scene.views][:1] == ["door"]
    np.testing.assert_allclose(np.asarray(scene.view("door").position), DOOR["position"], rtol=F32_EPS)
    np.testing.assert_allclose(np.asarray(scene.sky_radiance), DAYLIGHT_SKY_RADIANCE, rtol=F32_EPS)
    np.testing.assert_allclose(np.asarray(scene.sun.direction), sun_direction(90.0, 35.0), atol=4 * F32_EPS)
    check_scenes([cfg])  # lit, and has the view: passes


def test_a_dark_scene_is_refused_for_a_bake_not_for_a_placement(room):
    with pytest.raises(SceneError, match=r"room\.obj: the scene has no light.*room\.probeplace\.yaml"):
        check_scenes([_cfg(room, eval={"view": "overview"})])
    check_scenes([_cfg(room, bake={"enabled": False}, eval={"enabled": False})])  # placement needs none


def test_scene_overrides_are_checked_like_a_sidecar(room):
    with pytest.raises(
        ConfigError, match=r"^scene\.overrides: sun\.elevation: must be in \[-90, 90\], got 120"
    ):
        _cfg(room, {"sun": {"azimuth": 0, "elevation": 120}})
    with pytest.raises(ConfigError, match=r"^scene\.overrides: colour: unknown key; known keys: cameras"):
        _cfg(room, {"colour": "red"})
    with pytest.raises(ConfigError, match=r"^scene\.overrides: cameras\.door\.look_at: equals the position"):
        _cfg(room, {"cameras": {"door": {"position": [1, 1, 1], "look_at": [1, 1, 1]}}})


def test_each_override_value_is_a_run_folder_of_its_own(room):
    """A sweep over the sun gets one folder per value; a run without overrides keeps its old name."""
    plain = _cfg(room)
    assert run_name(plain) == "room__skeleton__bauto__s0"
    names = {run_name(_cfg(room, {"sun": {"azimuth": 90, "elevation": el}})) for el in (20, 40)}
    assert len(names) == 2 and all(n.startswith(run_name(plain) + "__scene=") for n in names)


def test_check_scenes_loads_each_scene_once_and_names_the_missing_view(monkeypatch):
    """A sweep over two scenes with one view name: the scene lacking it is refused, naming its views,
    before any run starts; a scene used by several runs is loaded once."""
    import probeplace.scene as scene_pkg

    real, loaded = scene_pkg.load_scene, []

    def counting(name, **kw):
        loaded.append(name)
        return real(name, **kw)

    monkeypatch.setattr(scene_pkg, "load_scene", counting)
    cornell = [to_config({"seed": s}) for s in (0, 1)]
    check_scenes(cornell)
    assert loaded == ["cornell_box"]
    rooms = to_config({"scene": {"name": "rooms"}})  # eval.view stays "front"
    with pytest.raises(
        ConfigError, match=r"^eval\.view: scene 'rooms' has no view 'front'; views: \['lit_room', 'doorway'"
    ):
        check_scenes([*cornell, rooms])


def test_run_refuses_an_unwritable_results_folder_before_loading_the_scene(tmp_path, monkeypatch):
    """``run`` from Python (no Hydra, no precheck): a results folder under a file is one ConfigError
    naming ``results_dir``, at once, and nothing is written."""
    import probeplace.experiment._run as run_mod

    def never(*a, **kw):
        raise AssertionError("the scene was loaded before the results folder was checked")

    monkeypatch.setattr(run_mod, "_load_unmoved", never)
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(
        ConfigError, match=r"^results_dir: cannot create .*/file/results/default: .*/file is a file"
    ):
        run({"results_dir": str(blocker / "results"), "eval": {"enabled": False}})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_a_view_camera_inside_a_solid_is_refused_before_any_run(room, no_slow_work):
    """The runner's precheck holds the evaluate command's camera check (issue 31): a view inside the lamp
    box of the room is refused naming the overrides key and the camera, before any caster, bake or run."""
    from tests.scene.sidecar_util import LAMP

    inside = [(a + b) / 2 for a, b in zip(*LAMP, strict=True)]
    cams = {"door": DOOR, "lamp": {"position": inside, "look_at": [2.0, 0.2, 4.0]}}
    with pytest.raises(ConfigError, match=r"cameras\.lamp: position .* is inside solid geometry"):
        check_scenes([_cfg(room, {**LIGHT, "cameras": cams}, eval={"view": "lamp"})])
    check_scenes([_cfg(room, {**LIGHT, "cameras": {"door": DOOR}}, eval={"view": "door"})])  # free: passes
