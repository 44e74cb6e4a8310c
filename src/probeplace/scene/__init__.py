"""Scenes: loaders, built-in scenes, materials, lights and views (see docs/scenes.md).

The plain-Python names (the sidecar config, the search path and scene list, the built-in scene registry,
the daylight constants, the CLI scene options) load eagerly; the rest loads on first use (PEP 562
``__getattr__``): it imports JAX, and ``probeplace --help`` and ``probeplace scenes`` must not.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._core._lazy import lazy_exports
from ._daylight import DAYLIGHT_SKY_RADIANCE as DAYLIGHT_SKY_RADIANCE
from ._daylight import DAYLIGHT_SUN_IRRADIANCE as DAYLIGHT_SUN_IRRADIANCE
from ._known import KNOWN_SCENES as KNOWN_SCENES
from ._registry import BUILTIN_SCENES as BUILTIN_SCENES
from ._search import SCENE_EXTENSIONS as SCENE_EXTENSIONS
from ._search import SCENE_PATH_ENV as SCENE_PATH_ENV
from ._search import SceneEntry as SceneEntry
from ._search import find_scene_file as find_scene_file
from ._search import list_scenes as list_scenes
from ._search import looks_like_path as looks_like_path
from ._search import scene_search_path as scene_search_path
from ._sidecar import SIDECAR_SUFFIX as SIDECAR_SUFFIX
from ._sidecar import CameraSpec as CameraSpec
from ._sidecar import EmitterSpec as EmitterSpec
from ._sidecar import MaterialSpec as MaterialSpec
from ._sidecar import SceneConfig as SceneConfig
from ._sidecar import SunSpec as SunSpec
from ._sidecar import merge_scene_configs as merge_scene_configs
from ._sidecar import no_light_hint as no_light_hint
from ._sidecar import parse_scene_config as parse_scene_config
from ._sidecar import read_sidecar as read_sidecar
from ._sidecar import sidecar_path as sidecar_path
from ._sidecar_cli import parse_camera as parse_camera
from ._sidecar_cli import parse_sky as parse_sky
from ._sidecar_cli import parse_sun as parse_sun
from ._sidecar_cli import scene_overrides as scene_overrides

# name -> the private module defining it (each imports JAX)
_LAZY = {
    **dict.fromkeys(("build_scene", "crease_normals", "make_camera", "make_materials", "make_sun"), "_build"),
    "cornell_box": "_cornell",
    "courtyard": "_courtyard",
    **dict.fromkeys(("load_scene", "load_scene_file", "scene_config_layers", "scene_layers"), "_load"),
    "derived_views": "_raw",
    **dict.fromkeys(("PreviewMesh", "preview_mesh", "srgb8"), "_preview"),
    **dict.fromkeys(
        ("ROOMS_DARK_ROOM_BOUNDS", "ROOMS_LIT_ROOM_BOUNDS", "ROOMS_WALL_THICKNESS", "rooms"), "_rooms"
    ),
    **dict.fromkeys(("apply_scene_config", "camera_origin"), "_sidecar_apply"),
    **dict.fromkeys(("sun_direction", "sun_from_irradiance"), "_sky"),
    **dict.fromkeys(("TEMPLE_UNDER_STAIRS_BOX", "temple"), "_temple"),
    **dict.fromkeys(("axis_angle_rotation", "transform_scene"), "_transform"),
    "scene_summary": "_summary",
    "read_gltf_json": "_gltf",
}
__all__ = [
    "KNOWN_SCENES",
    "SCENE_EXTENSIONS",
    "SCENE_PATH_ENV",
    "SceneEntry",
    "find_scene_file",
    "list_scenes",
    "looks_like_path",
    "scene_search_path",
    "BUILTIN_SCENES",
    "SIDECAR_SUFFIX",
    "CameraSpec",
    "EmitterSpec",
    "MaterialSpec",
    "SceneConfig",
    "SunSpec",
    "merge_scene_configs",
    "no_light_hint",
    "parse_scene_config",
    "read_sidecar",
    "sidecar_path",
    "parse_camera",
    "parse_sky",
    "parse_sun",
    "scene_overrides",
    "DAYLIGHT_SKY_RADIANCE",
    "DAYLIGHT_SUN_IRRADIANCE",
    *_LAZY,
]

if TYPE_CHECKING:  # what static checkers and IDEs see; __getattr__ gives the same at run time
    from ._build import build_scene as build_scene
    from ._build import crease_normals as crease_normals
    from ._build import make_camera as make_camera
    from ._build import make_materials as make_materials
    from ._build import make_sun as make_sun
    from ._cornell import cornell_box as cornell_box
    from ._courtyard import courtyard as courtyard
    from ._gltf import read_gltf_json as read_gltf_json
    from ._load import load_scene as load_scene
    from ._load import load_scene_file as load_scene_file
    from ._load import scene_config_layers as scene_config_layers
    from ._load import scene_layers as scene_layers
    from ._preview import PreviewMesh as PreviewMesh
    from ._preview import preview_mesh as preview_mesh
    from ._preview import srgb8 as srgb8
    from ._raw import derived_views as derived_views
    from ._rooms import ROOMS_DARK_ROOM_BOUNDS as ROOMS_DARK_ROOM_BOUNDS
    from ._rooms import ROOMS_LIT_ROOM_BOUNDS as ROOMS_LIT_ROOM_BOUNDS
    from ._rooms import ROOMS_WALL_THICKNESS as ROOMS_WALL_THICKNESS
    from ._rooms import rooms as rooms
    from ._sidecar_apply import apply_scene_config as apply_scene_config
    from ._sidecar_apply import camera_origin as camera_origin
    from ._sky import sun_direction as sun_direction
    from ._sky import sun_from_irradiance as sun_from_irradiance
    from ._summary import scene_summary as scene_summary
    from ._temple import TEMPLE_UNDER_STAIRS_BOX as TEMPLE_UNDER_STAIRS_BOX
    from ._temple import temple as temple
    from ._transform import axis_angle_rotation as axis_angle_rotation
    from ._transform import transform_scene as transform_scene


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals(), __all__)
