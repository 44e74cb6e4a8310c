"""The scene sidecar (``<stem>.probeplace.yaml``): a room with no light made renderable by it, emitters
and materials by name, units and up axis, and the known-scene layer."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from probeplace._core import ConfigError, SceneError
from probeplace.scene import (
    DAYLIGHT_SKY_RADIANCE,
    DAYLIGHT_SUN_IRRADIANCE,
    load_scene,
    sidecar_path,
    sun_direction,
)
from probeplace.scene.light._sky import SUN_ANGULAR_RADIUS
from tests.scene.sidecar_util import LAMP, ROOM_HI, write_room_obj

F32_EPS = float(np.finfo(np.float32).eps)

SIDECAR = """\
# sun and sky through the window (+Z wall), two cameras
sun:
  azimuth: 90        # toward +Z: through the window
  elevation: 35
  irradiance: [8.0, 7.5, 6.6]
sky: daylight
cameras:
  door:
    position: [2.0, 1.6, 0.5]
    look_at: [2.0, 1.0, 5.0]
    fov: 60
  corner:
    position: [0.5, 2.5, 0.5]
    look_at: [3.5, 0.5, 4.5]
    up: [0, 1, 0]
    fov: 75
"""


@pytest.fixture
def room(tmp_path):
    return write_room_obj(tmp_path)


def _sun_irradiance(sun) -> np.ndarray:
    r = float(sun.angular_radius)
    return np.asarray(sun.radiance, np.float64) * 4 * np.pi * np.sin(0.5 * r) ** 2


def test_sidecar_name_rule(tmp_path):
    assert sidecar_path(tmp_path / "room.glb") == tmp_path / "room.probeplace.yaml"
    assert sidecar_path("a/b.v2.obj").name == "b.v2.probeplace.yaml"


def test_no_light_names_the_sidecar_keys(room, caplog):
    with caplog.at_level(logging.WARNING):
        scene = load_scene(room)
    assert not scene.has_light
    for word in ("no light", "room.probeplace.yaml", "sun", "sky", "emitters"):
        assert word in caplog.text
    with pytest.raises(SceneError, match=r"no light.*room\.probeplace\.yaml.*keys: sun, sky, emitters"):
        load_scene(room, require_light=True)


def test_sidecar_lights_and_frames_a_dark_room(room):
    sidecar_path(room).write_text(SIDECAR)
    scene = load_scene(room, require_light=True)
    assert scene.has_light and scene.emissive_tris.shape == (0,)
    np.testing.assert_allclose(np.asarray(scene.sun.direction), sun_direction(90.0, 35.0), atol=4 * F32_EPS)
    np.testing.assert_allclose(_sun_irradiance(scene.sun), DAYLIGHT_SUN_IRRADIANCE, rtol=1e-5)  # float32
    np.testing.assert_allclose(float(scene.sun.angular_radius), SUN_ANGULAR_RADIUS, rtol=F32_EPS)
    np.testing.assert_allclose(np.asarray(scene.sky_radiance), DAYLIGHT_SKY_RADIANCE, rtol=F32_EPS)
    assert [v.name for v in scene.views] == ["door", "corner"]  # two given: no derived view added
    corner = scene.view("corner")
    np.testing.assert_allclose(np.asarray(corner.position), [0.5, 2.5, 0.5], rtol=F32_EPS)
    assert float(corner.fov_y_deg) == 75.0


def test_sidecar_camera_renders(room):
    """A tiny render through a sidecar camera: finite and lit (sunlight and sky through the window)."""
    from probeplace.render import RenderConfig, render

    sidecar_path(room).write_text(SIDECAR)
    scene = load_scene(room)
    img = np.asarray(
        render(
            scene, "door", RenderConfig(width=8, height=8, spp=2, max_depth=3, progress=False), key=0
        ).image("full")
    )
    assert img.shape == (8, 8, 3) and np.all(np.isfinite(img))
    assert img.max() > 0


def test_emitters_by_material_name(room):
    sidecar_path(room).write_text("emitters:\n  lamp: 5\n")
    scene = load_scene(room, require_light=True)
    i = scene.materials.names.index("lamp")
    np.testing.assert_allclose(np.asarray(scene.materials.emission[i]), [5.0, 5.0, 5.0])
    lamp_tris = np.flatnonzero(np.asarray(scene.tri_material) == i)
    assert len(lamp_tris) == 12  # the lamp box, and nothing else
    np.testing.assert_array_equal(np.sort(np.asarray(scene.emissive_tris)), lamp_tris)

    sidecar_path(room).write_text("emitters:\n  lamp: {strength: 2, color: [1.0, 0.5, 0.25]}\n")
    scene = load_scene(room)
    np.testing.assert_allclose(np.asarray(scene.materials.emission[i]), [2.0, 1.0, 0.5])


def test_materials_replace_and_add(room):
    sidecar_path(room).write_text(
        "materials:\n"
        "  floor: {roughness: 0.2, metallic: 0.0}\n"
        "  glass_lamp: {base_color: [0.9, 0.9, 1.0], roughness: 0.05, parts: [lamp]}\n"
        "emitters:\n"
        "  glass_lamp: 3\n"  # an emitter may name a material the sidecar adds
    )
    scene = load_scene(room)
    m = scene.materials
    floor = m.names.index("floor")
    assert float(m.roughness[floor]) == pytest.approx(0.2)
    np.testing.assert_allclose(np.asarray(m.base_color[floor]), [0.5, 0.4, 0.3], rtol=F32_EPS)  # kept
    new = m.names.index("glass_lamp")
    lamp_part = scene.part_names.index("lamp")
    assert np.all(np.asarray(scene.tri_material)[np.asarray(scene.tri_part) == lamp_part] == new)
    assert scene.emissive_tris.shape == (12,)


def test_units_and_z_up(tmp_path):
    """A Z-up file in centimetres, its sidecar in the file's own frame: the loaded scene is +Y up and,
    with scale_to_metres, in metres; cameras and an az/el sun come out where they would in the Y-up room."""
    path = write_room_obj(tmp_path, "zroom", up_axis="z")
    sidecar_path(path).write_text(
        "units: cm\nup_axis: z\nscale_to_metres: true\nsun: {azimuth: 90, elevation: 35}\n"
        # file frame: room point (x, y, z) is file (x, -z, y); up defaults to the file's +Z
        "cameras:\n  door: {position: [2, -0.5, 1.6], look_at: [2, -5, 1.0]}\n"
    )
    scene = load_scene(path)
    assert scene.unit_m == 1.0
    lo, hi = np.asarray(scene.bounds, np.float64)
    np.testing.assert_allclose(hi, 0.01 * (np.asarray(ROOM_HI) + 0.1), rtol=1e-6)  # float32 cm → m
    np.testing.assert_allclose(lo, [-0.001] * 3, rtol=1e-6)
    door = scene.view("door")
    np.testing.assert_allclose(np.asarray(door.position), [0.02, 0.016, 0.005], rtol=1e-6)
    np.testing.assert_allclose(np.asarray(door.up), [0.0, 1.0, 0.0], atol=F32_EPS)
    np.testing.assert_allclose(np.asarray(scene.sun.direction), sun_direction(90.0, 35.0), atol=4 * F32_EPS)

    sidecar_path(path).write_text("units: cm\n")  # units alone: recorded, geometry kept in file units
    scene = load_scene(path)
    assert scene.unit_m == 0.01
    np.testing.assert_allclose(np.asarray(scene.bounds)[1], [4.1, 0.1, 3.1], rtol=1e-6)  # still Z-up


def test_lamp_box_position_survives_up_axis(tmp_path):
    """Materials follow their triangles through the up-axis turn: the lamp box sits where it should."""
    path = write_room_obj(tmp_path, "zroom", up_axis="z")
    sidecar_path(path).write_text("up_axis: z\nemitters: {lamp: 1}\n")
    scene = load_scene(path)
    tris = np.asarray(scene.triangles)[np.asarray(scene.emissive_tris)].reshape(-1, 3)
    np.testing.assert_allclose(tris.min(0), LAMP[0], atol=1e-6)  # float32 round-off of 0.1-ish values
    np.testing.assert_allclose(tris.max(0), LAMP[1], atol=1e-6)


def test_overrides_apply_to_builtins():
    scene = load_scene(
        "cornell_box",
        overrides={
            "sky": "daylight",
            "cameras": {"low": {"position": [278, 50, -600], "look_at": [278, 273, 0]}},
        },
    )
    np.testing.assert_allclose(np.asarray(scene.sky_radiance), DAYLIGHT_SKY_RADIANCE, rtol=F32_EPS)
    assert scene.views[-1].name == "low" and len(scene.views) == 3


def test_sidecar_errors_come_before_the_scene_file_is_read(tmp_path):
    """A bad sidecar is refused even when the scene file is corrupt: it is checked first (cheap)."""
    path = tmp_path / "broken.glb"
    path.write_bytes(b"not a glb at all")
    sidecar_path(path).write_text("sun: {azimuth: 10, elevation: 120}\n")
    with pytest.raises(
        ConfigError, match=r"broken\.probeplace\.yaml: sun\.elevation: must be in \[-90, 90\]"
    ):
        load_scene(path)


def test_known_scene_layer_is_a_sidecar_mapping():
    from probeplace.scene import KNOWN_SCENES, parse_scene_config

    for stem, mapping in KNOWN_SCENES.items():
        cfg = parse_scene_config(mapping, stem)
        assert cfg.unit_m is not None and len(cfg.cameras) >= 2
    sponza = parse_scene_config(KNOWN_SCENES["crytek_sponza"])
    assert (sponza.sun.azimuth_deg, sponza.sun.elevation_deg) == (170.0, 65.0)


def test_docs_example_is_a_valid_sidecar():
    """The full example of docs/scenes.md parses (its names belong to an imagined scene: not loaded)."""
    import re
    from pathlib import Path

    import yaml

    from probeplace.scene import parse_scene_config

    doc = (Path(__file__).resolve().parents[2] / "docs" / "scenes.md").read_text()
    block = re.search(r"```yaml\n(# room\.probeplace\.yaml.*?)```", doc, re.S)
    assert block is not None
    cfg = parse_scene_config(yaml.safe_load(block.group(1)), "docs")
    assert (cfg.unit_m, cfg.up_axis, cfg.sun.elevation_deg) == (0.01, "z", 35.0)
    assert list(cfg.cameras) == ["door", "corner"] and set(cfg.emitters) == {"lamp_shade", "neon"}


def test_sidecar_found_with_a_scene_on_the_search_path(tmp_path):
    from probeplace.scene import list_scenes

    room = write_room_obj(tmp_path, "lounge")
    sidecar_path(room).write_text("sky: 0.5\n")
    scene = load_scene("lounge", search_path=[tmp_path])
    np.testing.assert_allclose(np.asarray(scene.sky_radiance), [0.5] * 3, rtol=F32_EPS)
    entry = next(e for e in list_scenes([tmp_path]) if e.name == "lounge")
    assert entry.sidecar == str(sidecar_path(room))
