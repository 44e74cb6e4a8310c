"""Every refused sidecar value and one-line CLI value: a ConfigError of one line naming the key."""

from __future__ import annotations

import re

import pytest

from probeplace._core import ConfigError
from probeplace.scene import (
    load_scene,
    parse_camera,
    parse_scene_config,
    parse_sky,
    parse_sun,
    scene_overrides,
    sidecar_path,
)
from tests.scene.sidecar_util import write_room_obj

CAM = {"position": [0, 1, 0], "look_at": [0, 1, 1]}

# (sidecar mapping, message regex): checked without any scene
BAD_MAPPINGS = [
    ({"sunn": {}}, r"S: sunn: unknown key; known keys: cameras, emitters, .*sun"),
    ({"sun": {"azimuth": 1, "elevation": 2, "colour": 1}}, r"S: sun\.colour: unknown key; known keys: .*az"),
    ({"sun": "bright"}, r"S: sun: must be a mapping"),
    ({"sun": {"azimuth": 10, "elevation": 120}}, r"S: sun\.elevation: must be in \[-90, 90\], got 120"),
    ({"sun": {"azimuth": "east", "elevation": 20}}, r"S: sun\.azimuth: must be a finite number, got 'east'"),
    ({"sun": {"azimuth": 10}}, r"S: sun: elevation is missing"),
    ({"sun": {"irradiance": 3}}, r"S: sun: give direction: \[x, y, z\] or azimuth and elevation"),
    ({"sun": {"direction": [0, 0, 0]}}, r"S: sun\.direction: must be a non-zero vector"),
    ({"sun": {"direction": [0, 1]}}, r"S: sun\.direction: must be 3 finite numbers"),
    ({"sun": {"direction": [0, 1, 0], "az": 3, "el": 4}}, r"S: sun: give either direction or azimuth"),
    ({"sun": {"az": 3, "azimuth": 4, "el": 5}}, r"S: sun\.azimuth: azimuth is given twice"),
    ({"sun": {"dir": [0, 1, 0], "irradiance": 1, "radiance": 1}}, r"S: sun: give irradiance or radiance"),
    (
        {"sun": {"dir": [0, 1, 0], "irradiance": -1}},
        r"S: sun\.irradiance: must be one number or 3 non-negative",
    ),
    ({"sun": {"dir": [0, 1, 0], "angular_diameter": 0}}, r"S: sun\.angular_diameter: must be in \(0, 30\]"),
    ({"sky": "bright"}, r"S: sky: must be 'daylight', 'none', one number or \[r, g, b\]"),
    ({"sky": [0.1, 0.2]}, r"S: sky: must be one number or 3 non-negative"),
    ({"cameras": [CAM]}, r"S: cameras: must be a mapping"),
    ({"cameras": {"a": {"position": [0, 1, 0]}}}, r"S: cameras\.a: look_at is missing"),
    ({"cameras": {"a": {**CAM, "look_at": [0, 1, 0]}}}, r"S: cameras\.a\.look_at: equals the position"),
    ({"cameras": {"a": {**CAM, "fov": 0}}}, r"S: cameras\.a\.fov: must be in \(0, 180\), got 0"),
    ({"cameras": {"a": {**CAM, "fov": 180}}}, r"S: cameras\.a\.fov: must be in \(0, 180\), got 180"),
    ({"cameras": {"a": {**CAM, "fov": True}}}, r"S: cameras\.a\.fov: must be a finite number, got True"),
    (
        {"cameras": {"a": {**CAM, "up": [0, 0, 2]}}},
        r"S: cameras\.a\.up: is parallel to the viewing direction",
    ),
    ({"cameras": {"a": {**CAM, "zoom": 2}}}, r"S: cameras\.a\.zoom: unknown key"),
    ({"emitters": {"lamp": -1}}, r"S: emitters\.lamp: must be in \[0, inf\], got -1"),
    ({"emitters": {"lamp": {"color": [1, 1, 1]}}}, r"S: emitters\.lamp: strength is missing"),
    ({"emitters": ["lamp"]}, r"S: emitters: must be a mapping"),
    (
        {"materials": {"m": {"base_color": [1.5, 0, 0]}}},
        r"S: materials\.m\.base_color: an albedo must be in \[0, 1\]",
    ),
    ({"materials": {"m": {"roughness": 2}}}, r"S: materials\.m\.roughness: must be in \[0, 1\], got 2"),
    ({"materials": {"m": {"parts": []}}}, r"S: materials\.m\.parts: must be a part name or a list"),
    ({"units": "furlong"}, r"S: units: unknown unit 'furlong'; use one of m, cm, mm"),
    ({"units": 0}, r"S: units: must be in \(0, inf\], got 0"),
    ({"up_axis": "x"}, r"S: up_axis: must be 'y' or 'z', got 'x'"),
    ({"keep_file_cameras": "yes"}, r"S: keep_file_cameras: must be true or false"),
    (["sun"], r"S: must be a mapping"),
]


@pytest.mark.parametrize(("mapping", "message"), BAD_MAPPINGS, ids=[m for _, m in BAD_MAPPINGS])
def test_bad_sidecar_values(mapping, message):
    with pytest.raises(ConfigError, match=message) as info:
        parse_scene_config(mapping, "S")
    assert "\n" not in str(info.value)


# (sidecar text, message regex): checked against the room's materials and parts, or as YAML
BAD_FOR_THE_ROOM = [
    (
        "emitters: {lampp: 5}",
        r"room\.probeplace\.yaml: emitters\.lampp: no material of that name; "
        r"materials: 'floor', 'lamp', 'wall'",
    ),
    ("materials: {glass: {roughness: 0}}", r"materials\.glass: not a material of the scene .* needs parts"),
    (
        "materials: {glass: {parts: [window]}}",
        r"materials\.glass\.parts: no part 'window' in the scene; parts:",
    ),
    (
        "cameras: {top: {position: [2, 3, 2], look_at: [2, 0, 2]}}",
        r"cameras\.top \(default up\): is parallel",
    ),
    ("sun: [1, 2", r"room\.probeplace\.yaml: not valid YAML at line 2"),
    ("- sun\n- sky\n", r"room\.probeplace\.yaml: must be a mapping"),
]


@pytest.mark.parametrize(("text", "message"), BAD_FOR_THE_ROOM, ids=[t for t, _ in BAD_FOR_THE_ROOM])
def test_bad_sidecar_for_a_scene(tmp_path, text, message):
    room = write_room_obj(tmp_path)
    sidecar_path(room).write_text(text + "\n")
    with pytest.raises(ConfigError, match=message) as info:
        load_scene(room)
    assert "\n" not in str(info.value)


def test_overrides_errors_name_the_layer(tmp_path):
    room = write_room_obj(tmp_path)
    with pytest.raises(ConfigError, match=r"^overrides: emitters\.nope: no material"):
        load_scene(room, overrides={"emitters": {"nope": 1}})


def test_empty_sidecar_is_no_config(tmp_path):
    room = write_room_obj(tmp_path)
    sidecar_path(room).write_text("# nothing yet\n")
    assert not load_scene(room).has_light


# ------------------------------------------------------------------------------ one-line CLI values


def test_parse_sun_forms():
    assert parse_sun("az=120,el=35,irradiance=8") == {"azimuth": 120.0, "elevation": 35.0, "irradiance": 8.0}
    assert parse_sun("dir=0.3,1,0.2, radiance=1,2,3, angular_diameter=1") == {
        "direction": [0.3, 1.0, 0.2],
        "radiance": [1.0, 2.0, 3.0],
        "angular_diameter": 1.0,
    }
    assert parse_sun("none") == "none"


def test_parse_sky_forms():
    assert parse_sky("daylight") == "daylight"
    assert parse_sky("none") == "none"
    assert parse_sky("0.5") == [0.5, 0.5, 0.5]
    assert parse_sky(" 0.4, 0.5,0.6 ") == [0.4, 0.5, 0.6]


def test_parse_camera_form():
    name, spec = parse_camera("name=door,pos=1,1.6,4,look_at=0,1,0,fov=60")
    assert name == "door"
    assert spec == {"position": [1.0, 1.6, 4.0], "look_at": [0.0, 1.0, 0.0], "fov": 60.0}
    assert parse_camera("pos=0,0,0,look_at=1,0,0")[0] == "camera"


BAD_CLI = [
    (parse_sun, "az=120,el=135", r"^--sun: el: must be in \[-90, 90\], got 135$"),
    (parse_sun, "azz=120,el=35", r"^--sun: azz: unknown key; known keys: angular_diameter, az, azimuth"),
    (parse_sun, "120,35", r"^--sun: '120' has no key; write key=value pairs"),
    (parse_sun, "az=,el=3", r"^--sun: az: no value after '='$"),
    (parse_sun, "az=1,az=2,el=3", r"^--sun: az: given twice$"),
    (parse_sun, "dir=0,0,0", r"^--sun: dir: must be a non-zero vector"),
    (parse_sun, "dir=0,x,1", r"^--sun: dir: 'x' is not a number$"),
    (parse_sun, "", r"^--sun: empty value"),
    (parse_sky, "bright", r"^--sky: must be 'daylight', 'none', one number or r,g,b, got 'bright'$"),
    (parse_sky, "1,2", r"^--sky: must be one number or 3 non-negative"),
    (parse_sky, "-1", r"^--sky: must be one number or 3 non-negative"),
    (parse_camera, "name=a,pos=1,1,1,look_at=1,1,1", r"^--camera a: look_at: equals the position"),
    (
        parse_camera,
        "name=a,pos=1,1,1,look_at=0,0,0,fov=200",
        r"^--camera a: fov: must be in \(0, 180\), got 200$",
    ),
    (parse_camera, "name=a,pos=1,1,1", r"^--camera a: look_at is missing"),
    (parse_camera, "name=a,pos=1,1,1,look_at=0,0,0,roll=3", r"^--camera a: roll: unknown key"),
]


@pytest.mark.parametrize(("fn", "text", "message"), BAD_CLI, ids=[t or "empty" for _, t, _ in BAD_CLI])
def test_bad_cli_values(fn, text, message):
    with pytest.raises(ConfigError, match=message):
        fn(text)


def test_scene_overrides():
    assert scene_overrides() == {}
    out = scene_overrides(sun="az=1,el=2", cameras=["name=a,pos=0,0,0,look_at=1,0,0"])
    assert set(out) == {"sun", "cameras"} and set(out["cameras"]) == {"a"}
    parse_scene_config(out, "overrides")  # the result is a valid sidecar layer
    with pytest.raises(ConfigError, match=re.escape("--camera: name 'a' is given twice")):
        scene_overrides(cameras=["name=a,pos=0,0,0,look_at=1,0,0", "name=a,pos=0,0,0,look_at=0,1,0"])
