"""Scenes: loaders, built-in scenes, materials, lights and views (see docs/scenes.md), grouped by role:

* ``_load``, ``_search``: ``load_scene`` and the search path / scene list it resolves names through;
* ``_build``, ``_primitives``, ``_raw``, ``_transform``: building a checked Scene (from triangles, from mesh
  primitives, from what a file loader read) and moving it rigidly;
* ``_summary``, ``_preview``: a loaded scene as plain data and as a person sees it;
* ``files/``: the glTF, OBJ and PLY loaders; ``builtin/``: the registry and the scenes made in code;
* ``config/``: the sidecar config (parsing, CLI values, known scenes' layers, applying it);
* ``light/``: the daylight constants, sun and sky.

Each group's ``__init__`` is its face for the rest of the package; this one is the stage's. The plain-Python
names (the sidecar config, the search path and scene list, the built-in scene registry, the daylight
constants, the CLI scene options) load eagerly; the rest loads on first use (PEP 562 ``__getattr__``): it
imports JAX, and ``probeplace --help`` and ``probeplace scenes`` must not.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._core._lazy import lazy_exports
from ._search import SCENE_EXTENSIONS as SCENE_EXTENSIONS
from ._search import SCENE_PATH_ENV as SCENE_PATH_ENV
from ._search import SceneEntry as SceneEntry
from ._search import find_scene_file as find_scene_file
from ._search import list_scenes as list_scenes
from ._search import looks_like_path as looks_like_path
from ._search import scene_search_path as scene_search_path
from .builtin import BUILTIN_SCENES as BUILTIN_SCENES
from .config import KNOWN_SCENES as KNOWN_SCENES
from .config import SIDECAR_SUFFIX as SIDECAR_SUFFIX
from .config import CameraSpec as CameraSpec
from .config import EmitterSpec as EmitterSpec
from .config import MaterialSpec as MaterialSpec
from .config import SceneConfig as SceneConfig
from .config import SunSpec as SunSpec
from .config import merge_scene_configs as merge_scene_configs
from .config import no_light_hint as no_light_hint
from .config import parse_camera as parse_camera
from .config import parse_scene_config as parse_scene_config
from .config import parse_sky as parse_sky
from .config import parse_sun as parse_sun
from .config import read_sidecar as read_sidecar
from .config import scene_overrides as scene_overrides
from .config import sidecar_path as sidecar_path
from .light import DAYLIGHT_SKY_RADIANCE as DAYLIGHT_SKY_RADIANCE
from .light import DAYLIGHT_SUN_IRRADIANCE as DAYLIGHT_SUN_IRRADIANCE

# name -> the module or group face defining it (each imports JAX)
_LAZY = {
    **dict.fromkeys(("build_scene", "crease_normals", "make_camera", "make_materials", "make_sun"), "_build"),
    "cornell_box": "builtin",
    "courtyard": "builtin",
    **dict.fromkeys(("load_scene", "load_scene_file", "scene_config_layers", "scene_layers"), "_load"),
    "derived_views": "_raw",
    **dict.fromkeys(("PreviewMesh", "preview_mesh", "srgb8"), "_preview"),
    **dict.fromkeys(
        ("ROOMS_DARK_ROOM_BOUNDS", "ROOMS_LIT_ROOM_BOUNDS", "ROOMS_WALL_THICKNESS", "rooms"), "builtin"
    ),
    **dict.fromkeys(("apply_scene_config", "camera_origin"), "config"),
    **dict.fromkeys(("sun_direction", "sun_from_irradiance"), "light"),
    **dict.fromkeys(("TEMPLE_UNDER_STAIRS_BOX", "temple"), "builtin"),
    **dict.fromkeys(("axis_angle_rotation", "transform_scene"), "_transform"),
    "scene_summary": "_summary",
    "read_gltf_json": "files",
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
    from ._load import load_scene as load_scene
    from ._load import load_scene_file as load_scene_file
    from ._load import scene_config_layers as scene_config_layers
    from ._load import scene_layers as scene_layers
    from ._preview import PreviewMesh as PreviewMesh
    from ._preview import preview_mesh as preview_mesh
    from ._preview import srgb8 as srgb8
    from ._raw import derived_views as derived_views
    from ._summary import scene_summary as scene_summary
    from ._transform import axis_angle_rotation as axis_angle_rotation
    from ._transform import transform_scene as transform_scene
    from .builtin import ROOMS_DARK_ROOM_BOUNDS as ROOMS_DARK_ROOM_BOUNDS
    from .builtin import ROOMS_LIT_ROOM_BOUNDS as ROOMS_LIT_ROOM_BOUNDS
    from .builtin import ROOMS_WALL_THICKNESS as ROOMS_WALL_THICKNESS
    from .builtin import TEMPLE_UNDER_STAIRS_BOX as TEMPLE_UNDER_STAIRS_BOX
    from .builtin import cornell_box as cornell_box
    from .builtin import courtyard as courtyard
    from .builtin import rooms as rooms
    from .builtin import temple as temple
    from .config import apply_scene_config as apply_scene_config
    from .config import camera_origin as camera_origin
    from .files import read_gltf_json as read_gltf_json
    from .light import sun_direction as sun_direction
    from .light import sun_from_irradiance as sun_from_irradiance


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals(), __all__)
