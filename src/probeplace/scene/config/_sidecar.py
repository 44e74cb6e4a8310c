"""The scene sidecar config: light, cameras, materials and units for a scene file, from YAML or a mapping.

File rule: ``<folder>/<stem>.<ext>`` (``room.glb``) is configured by ``<folder>/<stem>.probeplace.yaml``
(``room.probeplace.yaml``) when that file exists. The same keys come as a mapping from Python
(``load_scene(..., overrides=...)``) and from the one-line CLI values of :mod:`._sidecar_cli`.

Precedence, lowest first (docs/scenes.md, "Sidecar config"): what the file carries (materials, emissive
materials, glTF cameras, a ``KHR_lights_punctual`` directional light as the sun), then the built-in facts
about a known file (:data:`~probeplace.scene.KNOWN_SCENES`, in the same form), then the sidecar, then
programmatic overrides. A higher layer replaces ``sun``, ``sky``, ``units``, ``up_axis``,
``scale_to_metres`` and ``keep_file_cameras`` whole, and ``cameras``, ``materials``, ``emitters`` entry by
entry (by name).

Frames: vectors and points (``sun.direction``, camera ``position`` / ``look_at`` / ``up``) are in the
file's own frame and units, like its vertices, and are converted with the geometry (``up_axis``,
``scale_to_metres``). ``azimuth`` / ``elevation`` are about the up axis: elevation above the horizon,
azimuth from +X turning toward +Z of the loaded (+Y up) scene, i.e. toward −Y of a Z-up file.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..._core import ConfigError
from ..light import DAYLIGHT_SKY_RADIANCE, SUN_ANGULAR_RADIUS
from . import _config_values as cv

#: Suffix that replaces a scene file's extension to name its sidecar: room.glb -> room.probeplace.yaml.
SIDECAR_SUFFIX = ".probeplace.yaml"
#: Keys that give a scene light (named by the "no light" messages).
LIGHT_KEYS = ("sun", "sky", "emitters")
#: Metres per unit for the unit names ``units`` accepts.
UNIT_NAMES = {"m": 1.0, "cm": 0.01, "mm": 0.001, "km": 1000.0, "in": 0.0254, "ft": 0.3048}
#: Largest sun disk: sun_from_irradiance treats cos θ ≈ 1 across the disk (≤ 3.4% off at 15° radius).
MAX_SUN_DIAMETER_DEG = 30.0
#: The real sun's apparent diameter, degrees (2 × SUN_ANGULAR_RADIUS).
SUN_DIAMETER_DEG = math.degrees(2.0 * SUN_ANGULAR_RADIUS)
DEFAULT_FOV_DEG = 60.0


def sidecar_path(scene_path: str | os.PathLike) -> Path:
    """Where the sidecar of a scene file is: the file's extension replaced by ``.probeplace.yaml``."""
    return Path(scene_path).with_suffix(SIDECAR_SUFFIX)


def no_light_hint(scene_path: str | os.PathLike | None = None, *, stem: str | None = None) -> str:
    """The end of every "no light" message: which sidecar keys add light, and where the sidecar goes
    (beside ``scene_path``; or, from a loaded scene, ``stem``: a file scene's name is its file's stem)."""
    if scene_path is not None:
        where = sidecar_path(scene_path).name
    else:
        where = f"{stem or '<scene>'}{SIDECAR_SUFFIX}"
    return (
        f"add one with a sidecar {where} beside the scene file (keys: {', '.join(LIGHT_KEYS)}; "
        "see docs/scenes.md) or the overrides sun= / sky= (CLI --sun / --sky; runner scene.overrides)"
    )


@dataclasses.dataclass(frozen=True)
class SunSpec:
    """A sun: ``direction`` (file frame, toward the sun) or ``azimuth_deg`` + ``elevation_deg``; at most
    one of ``irradiance`` (on a surface facing it) and ``radiance`` (of its disk), linear RGB; neither
    means the daylight irradiance (``DAYLIGHT_SUN_IRRADIANCE``)."""

    direction: tuple[float, float, float] | None = None
    azimuth_deg: float | None = None
    elevation_deg: float | None = None
    irradiance: tuple[float, float, float] | None = None
    radiance: tuple[float, float, float] | None = None
    angular_diameter_deg: float = SUN_DIAMETER_DEG


@dataclasses.dataclass(frozen=True)
class CameraSpec:
    """A pinhole camera, file frame; ``up`` None means the file's up axis; ``fov_deg`` is vertical."""

    position: tuple[float, float, float]
    look_at: tuple[float, float, float]
    up: tuple[float, float, float] | None = None
    fov_deg: float = DEFAULT_FOV_DEG


@dataclasses.dataclass(frozen=True)
class MaterialSpec:
    """Replaces the given factors of a material (unset ones keep the file's; a new material starts from
    grey, rough, dielectric) and assigns it to the triangles of ``parts``."""

    base_color: tuple[float, float, float] | None = None
    roughness: float | None = None
    metallic: float | None = None
    parts: tuple[str, ...] = ()


@dataclasses.dataclass(frozen=True)
class EmitterSpec:
    """Makes a material's triangles emit radiance ``strength × color`` (strength 0 turns it off)."""

    strength: float
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)


#: ``sun: none`` — no sun, even if the file or a lower layer has one.
NO_SUN = "none"


@dataclasses.dataclass(frozen=True)
class SceneConfig:
    """A validated sidecar (or override) layer; ``None`` / empty fields are not set by this layer.

    Attributes:
        sun: a :class:`SunSpec`, or :data:`NO_SUN`.
        sky: constant sky radiance, linear RGB (``daylight`` → ``DAYLIGHT_SKY_RADIANCE``, ``none`` → 0).
        emitters, materials, cameras: by material / camera name, in the order given.
        keep_file_cameras: keep the file's own cameras beside ``cameras`` (default true).
        unit_m: metres per file unit.
        up_axis: ``"y"`` or ``"z"``: the file's up axis (Z-up files are turned to the scene's +Y up).
        scale_to_metres: scale the geometry by ``unit_m`` so the scene is in metres (``unit_m`` becomes 1).
        source: where the layer came from (for messages).
    """

    sun: SunSpec | str | None = None
    sky: tuple[float, float, float] | None = None
    emitters: Mapping[str, EmitterSpec] = dataclasses.field(default_factory=dict)
    materials: Mapping[str, MaterialSpec] = dataclasses.field(default_factory=dict)
    cameras: Mapping[str, CameraSpec] = dataclasses.field(default_factory=dict)
    keep_file_cameras: bool | None = None
    unit_m: float | None = None
    up_axis: str | None = None
    scale_to_metres: bool | None = None
    source: str = "<config>"


_TOP = {
    k: k
    for k in (
        "sun",
        "sky",
        "emitters",
        "materials",
        "cameras",
        "keep_file_cameras",
        "units",
        "up_axis",
        "scale_to_metres",
    )
}
_SUN = {
    "direction": "direction",
    "dir": "direction",
    "azimuth": "azimuth",
    "az": "azimuth",
    "elevation": "elevation",
    "el": "elevation",
    "irradiance": "irradiance",
    "radiance": "radiance",
    "angular_diameter": "angular_diameter",
}
_CAMERA = {"position": "position", "pos": "position", "look_at": "look_at", "up": "up", "fov": "fov"}
_MATERIAL = {k: k for k in ("base_color", "roughness", "metallic", "parts")}
_EMITTER = {"strength": "strength", "color": "color"}


def parse_sun_spec(value: Any, prefix: str) -> SunSpec | str:
    """A sun from its mapping (or ``none``); ``prefix`` locates it, e.g. ``"room.probeplace.yaml: sun."``."""
    at = prefix.rstrip(". :")
    if value is None or value == NO_SUN:
        return NO_SUN
    k = cv.keyed(cv.mapping(value, at), _SUN, prefix)
    spec: dict[str, Any] = {}
    if "direction" in k:
        if "azimuth" in k or "elevation" in k:
            raise ConfigError(f"{at}: give either direction or azimuth + elevation, not both")
        spec["direction"] = cv.direction3(k["direction"][1], k["direction"][0])
    elif "azimuth" in k and "elevation" in k:
        spec["azimuth_deg"] = cv.number(k["azimuth"][1], k["azimuth"][0])
        spec["elevation_deg"] = cv.number(k["elevation"][1], k["elevation"][0], lo=-90.0, hi=90.0)
    else:
        missing = "elevation" if "azimuth" in k else "azimuth" if "elevation" in k else None
        if missing is not None:
            raise ConfigError(f"{at}: {missing} is missing (azimuth and elevation come together)")
        raise ConfigError(f"{at}: give direction: [x, y, z] or azimuth and elevation (degrees)")
    if "irradiance" in k and "radiance" in k:
        raise ConfigError(f"{at}: give irradiance or radiance, not both")
    for key in ("irradiance", "radiance"):
        if key in k:
            spec[key] = cv.rgb(k[key][1], k[key][0])
    if "angular_diameter" in k:
        where, v = k["angular_diameter"]
        spec["angular_diameter_deg"] = cv.number(v, where, lo=0.0, hi=MAX_SUN_DIAMETER_DEG, open_lo=True)
    return SunSpec(**spec)


def parse_sky_value(value: Any, at: str) -> tuple[float, float, float]:
    """``daylight``, ``none``, one number (grey) or [r, g, b]: the constant sky radiance."""
    if value is None or value == "none":
        return (0.0, 0.0, 0.0)
    if value == "daylight":
        return tuple(float(c) for c in DAYLIGHT_SKY_RADIANCE)  # type: ignore[return-value]
    if isinstance(value, str):
        raise ConfigError(f"{at}: must be 'daylight', 'none', one number or [r, g, b], got {cv.show(value)}")
    return cv.rgb(value, at)


def parse_camera_spec(value: Any, prefix: str) -> CameraSpec:
    """A camera from its mapping; refuses look_at = position, a zero or view-parallel up, fov ∉ (0, 180)."""
    at = prefix.rstrip(". :")
    k = cv.keyed(cv.mapping(value, at), _CAMERA, prefix)
    for req in ("position", "look_at"):
        if req not in k:
            raise ConfigError(f"{at}: {req} is missing (a camera needs position and look_at)")
    pos = cv.vec3(k["position"][1], k["position"][0])
    look = cv.vec3(k["look_at"][1], k["look_at"][0])
    if pos == look:
        raise ConfigError(
            f"{k['look_at'][0]}: equals the position {list(pos)}; the camera would look nowhere"
        )
    up = cv.direction3(k["up"][1], k["up"][0]) if "up" in k else None
    if up is not None:
        check_up(pos, look, up, k["up"][0])
    fov = DEFAULT_FOV_DEG
    if "fov" in k:
        fov = cv.number(k["fov"][1], k["fov"][0], lo=0.0, hi=180.0, open_lo=True, open_hi=True)
    return CameraSpec(position=pos, look_at=look, up=up, fov_deg=fov)


def check_up(pos, look, up, at: str) -> None:
    """Refuse an up vector along the viewing direction (the image would have no defined 'up')."""
    f = [b - a for a, b in zip(pos, look, strict=True)]
    c = (f[1] * up[2] - f[2] * up[1], f[2] * up[0] - f[0] * up[2], f[0] * up[1] - f[1] * up[0])
    # sin(angle) below 1e-6: float32 cannot build a stable camera basis from the two
    if sum(x * x for x in c) <= 1e-12 * sum(x * x for x in f) * sum(x * x for x in up):
        raise ConfigError(
            f"{at}: is parallel to the viewing direction (look_at - position); choose another up"
        )


def _material(value: Any, prefix: str) -> MaterialSpec:
    at = prefix.rstrip(". :")
    k = cv.keyed(cv.mapping(value, at), _MATERIAL, prefix)
    out: dict[str, Any] = {}
    if "base_color" in k:
        where, v = k["base_color"]
        out["base_color"] = cv.rgb(v, where)
        if max(out["base_color"]) > 1.0:
            raise ConfigError(
                f"{where}: an albedo must be in [0, 1] per channel, got {list(out['base_color'])}"
            )
    for key in ("roughness", "metallic"):
        if key in k:
            out[key] = cv.number(k[key][1], k[key][0], lo=0.0, hi=1.0)
    if "parts" in k:
        where, v = k["parts"]
        v = [v] if isinstance(v, str) else v
        if not isinstance(v, list | tuple) or not v:
            raise ConfigError(f"{where}: must be a part name or a list of part names, got {cv.show(v)}")
        out["parts"] = tuple(cv.name(p, where) for p in v)
    return MaterialSpec(**out)


def _emitter(value: Any, prefix: str) -> EmitterSpec:
    at = prefix.rstrip(". :")
    if cv.is_number(value):
        return EmitterSpec(strength=cv.number(value, at, lo=0.0))
    k = cv.keyed(cv.mapping(value, at), _EMITTER, prefix)
    if "strength" not in k:
        raise ConfigError(f"{at}: strength is missing (emitted radiance = strength × color)")
    strength = cv.number(k["strength"][1], k["strength"][0], lo=0.0)
    color = cv.rgb(k["color"][1], k["color"][0]) if "color" in k else (1.0, 1.0, 1.0)
    return EmitterSpec(strength=strength, color=color)


def _named(value: Any, prefix: str, parse) -> dict:
    at = prefix.rstrip(". :")
    out = {}
    for n, v in cv.mapping(value, at).items():
        out[cv.name(n, at)] = parse(v, f"{prefix}{n}.")
    return out


def _units(value: Any, at: str) -> float:
    if isinstance(value, str):
        if value not in UNIT_NAMES:
            raise ConfigError(
                f"{at}: unknown unit {value!r}; use one of {', '.join(UNIT_NAMES)} "
                "or metres per unit (a number)"
            )
        return UNIT_NAMES[value]
    return cv.number(value, at, lo=0.0, open_lo=True)


def _up_axis(value: Any, at: str) -> str:
    v = str(value).lower().lstrip("+") if isinstance(value, str) else None
    if v not in ("y", "z"):
        raise ConfigError(f"{at}: must be 'y' or 'z', got {cv.show(value)}")
    return v


def parse_scene_config(data: Any, source: str = "<config>") -> SceneConfig:
    """Validate a sidecar mapping (the YAML's top level) into a :class:`SceneConfig`.

    Args:
        data: the mapping (``None``: an empty config), or an already parsed config (returned as is);
            typed ``Any`` because it is whatever the YAML held: anything else is refused here.
        source: what to call it in messages: the sidecar's file name, ``"overrides"``, ...

    Raises:
        ConfigError: one line naming the key: unknown key, wrong type, value out of range, a camera
            looking at its own position, a zero direction, ...
    """
    if isinstance(data, SceneConfig):
        return data
    if data is None:
        return SceneConfig(source=source)
    k = cv.keyed(cv.mapping(data, source), _TOP, f"{source}: ")
    out: dict[str, Any] = {"source": source}
    if "sun" in k:
        out["sun"] = parse_sun_spec(k["sun"][1], f"{k['sun'][0]}.")
    if "sky" in k:
        out["sky"] = parse_sky_value(k["sky"][1], k["sky"][0])
    if "emitters" in k:
        out["emitters"] = _named(k["emitters"][1], f"{k['emitters'][0]}.", _emitter)
    if "materials" in k:
        out["materials"] = _named(k["materials"][1], f"{k['materials'][0]}.", _material)
    if "cameras" in k:
        out["cameras"] = _named(k["cameras"][1], f"{k['cameras'][0]}.", parse_camera_spec)
    for key in ("keep_file_cameras", "scale_to_metres"):
        if key in k:
            out[key] = cv.boolean(k[key][1], k[key][0])
    if "units" in k:
        out["unit_m"] = _units(k["units"][1], k["units"][0])
    if "up_axis" in k:
        out["up_axis"] = _up_axis(k["up_axis"][1], k["up_axis"][0])
    return SceneConfig(**out)


def read_sidecar(path: str | os.PathLike) -> SceneConfig | None:
    """The validated sidecar of scene file ``path`` (see :func:`sidecar_path`), or None if there is none.

    Raises:
        ConfigError: the sidecar is not readable YAML, not a mapping, or a key is invalid.
    """
    import yaml  # PyYAML comes with hydra-core / omegaconf

    side = sidecar_path(path)
    if not side.is_file():
        return None
    try:
        data = yaml.safe_load(side.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(f"{side}: cannot read the sidecar ({type(e).__name__}: {e})") from e
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        line = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(e, "problem", None) or type(e).__name__
        raise ConfigError(f"{side}: not valid YAML{line} ({problem})") from e
    return parse_scene_config(data, side.name)


def merge_scene_configs(*layers: SceneConfig | None) -> SceneConfig:
    """Stack layers, lowest precedence first (module docstring): a later layer's set fields win; the
    named tables merge entry by entry."""
    out = SceneConfig(source="+".join(layer.source for layer in layers if layer is not None) or "<config>")
    for layer in layers:
        if layer is None:
            continue
        changes: dict[str, Any] = {}
        for f in dataclasses.fields(SceneConfig):
            v = getattr(layer, f.name)
            if f.name in ("emitters", "materials", "cameras"):
                changes[f.name] = {**getattr(out, f.name), **v}
            elif f.name != "source" and v is not None:
                changes[f.name] = v
        out = dataclasses.replace(out, **changes)
    return out
