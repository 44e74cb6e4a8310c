"""glTF cameras and ``KHR_lights_punctual`` suns read from a hand-written ``.gltf``, and the precedence
file < sidecar < programmatic overrides."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from probeplace.scene import load_scene, scene_overrides, sidecar_path, sun_direction
from probeplace.scene.light._sky import SUN_ANGULAR_RADIUS
from tests.scene.sidecar_util import write_gltf

F32_EPS = float(np.finfo(np.float32).eps)
# −45° about X as a glTF quaternion (x, y, z, w): the node's −Z (where a camera looks and a light
# shines) tilts down to (0, −sin45, −cos45), its +Z up to (0, sin45, cos45).
Q_X45 = [np.sin(np.deg2rad(-22.5)), 0.0, 0.0, np.cos(np.deg2rad(-22.5))]


def _irradiance(sun) -> np.ndarray:
    r = float(sun.angular_radius)
    return np.asarray(sun.radiance, np.float64) * 4 * np.pi * np.sin(0.5 * r) ** 2


@pytest.fixture
def gltf(tmp_path):
    return write_gltf(
        tmp_path / "plaza.gltf",
        camera_node={"name": "cam", "translation": [0.0, 1.5, 3.0], "rotation": Q_X45},
        light_nodes=[
            {"name": "sun_node", "rotation": Q_X45, "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"name": "bulb", "translation": [0, 1, 0], "extensions": {"KHR_lights_punctual": {"light": 1}}},
        ],
        lights=[
            {"type": "directional", "color": [1.0, 0.9, 0.8], "intensity": 5.0},
            {"type": "point", "name": "bulb", "intensity": 100.0},
        ],
    )


def test_gltf_camera_and_directional_light(gltf, caplog):
    with caplog.at_level(logging.WARNING):
        scene = load_scene(gltf, require_light=True)
    assert "point light 'bulb' skipped" in caplog.text
    cam = scene.view("cam")
    np.testing.assert_allclose(np.asarray(cam.position), [0.0, 1.5, 3.0], atol=F32_EPS)
    # −45° about X tilts the node's −Z forward axis down: (0, −sin45, −cos45)
    fwd = np.asarray(cam.look_at - cam.position, np.float64)
    np.testing.assert_allclose(fwd / np.linalg.norm(fwd), [0.0, -np.sqrt(0.5), -np.sqrt(0.5)], atol=1e-6)
    np.testing.assert_allclose(float(cam.fov_y_deg), np.degrees(0.8), rtol=F32_EPS)
    # the light shines along the node's −Z, so the sun lies along its +Z: (0, sin45, cos45)
    np.testing.assert_allclose(np.asarray(scene.sun.direction), [0.0, np.sqrt(0.5), np.sqrt(0.5)], atol=1e-6)
    np.testing.assert_allclose(_irradiance(scene.sun), [5.0, 4.5, 4.0], rtol=1e-5)  # float32 radiance
    np.testing.assert_allclose(float(scene.sun.angular_radius), SUN_ANGULAR_RADIUS, rtol=F32_EPS)


def test_precedence_file_then_sidecar_then_overrides(gltf):
    sidecar_path(gltf).write_text(
        "sun: {azimuth: 30, elevation: 50, irradiance: 2}\n"
        "sky: [0.1, 0.1, 0.1]\n"
        "cameras:\n"
        "  cam: {position: [1, 2, 3], look_at: [0, 0, 0]}\n"  # replaces the file's camera of that name
        "  extra: {position: [0, 1, 0], look_at: [1, 1, 0], fov: 40}\n"
    )
    file_only = load_scene(gltf, sidecar=False)
    side = load_scene(gltf)
    over = load_scene(
        gltf,
        overrides=scene_overrides(
            sun="az=200,el=20,irradiance=1", sky="0.3", cameras=["name=cam,pos=0,3,0.5,look_at=0,0,0,fov=30"]
        ),
    )
    # sun: file (directional light) < sidecar < overrides
    np.testing.assert_allclose(
        np.asarray(file_only.sun.direction), [0, np.sqrt(0.5), np.sqrt(0.5)], atol=1e-6
    )
    np.testing.assert_allclose(np.asarray(side.sun.direction), sun_direction(30.0, 50.0), atol=4 * F32_EPS)
    np.testing.assert_allclose(np.asarray(over.sun.direction), sun_direction(200.0, 20.0), atol=4 * F32_EPS)
    np.testing.assert_allclose(_irradiance(over.sun), [1.0, 1.0, 1.0], rtol=1e-5)  # float32 radiance
    # sky: none in the file < sidecar < overrides
    assert float(np.max(np.asarray(file_only.sky_radiance))) == 0.0
    np.testing.assert_allclose(np.asarray(side.sky_radiance), [0.1] * 3, rtol=F32_EPS)
    np.testing.assert_allclose(np.asarray(over.sky_radiance), [0.3] * 3, rtol=F32_EPS)
    # cameras merge by name: the file's "cam" is replaced in its place, "extra" stays through overrides
    assert [v.name for v in side.views] == ["cam", "extra"]
    np.testing.assert_allclose(np.asarray(side.view("cam").position), [1, 2, 3], atol=F32_EPS)
    assert [v.name for v in over.views] == ["cam", "extra"]
    np.testing.assert_allclose(np.asarray(over.view("cam").position), [0, 3, 0.5], atol=F32_EPS)
    assert float(over.view("cam").fov_y_deg) == 30.0


def test_sidecar_can_remove_the_file_sun_and_cameras(gltf):
    sidecar_path(gltf).write_text(
        "sun: none\nsky: daylight\nkeep_file_cameras: false\n"
        "cameras: {only: {position: [0, 1, 1], look_at: [0, 0, 0]}}\n"
    )
    scene = load_scene(gltf)
    assert scene.sun is None and scene.has_light
    assert scene.views[0].name == "only" and "cam" not in [v.name for v in scene.views]
