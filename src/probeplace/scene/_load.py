"""``load_scene``: built-in scenes by name, scene files by path, external scenes by name on a search path.

Search path (first match wins), used for names that are not built-in:

1. the ``search_path`` argument (a sequence of folders, or one string of folders joined by ``os.pathsep``);
2. the environment variable ``PROBEPLACE_SCENE_PATH`` (folders joined by ``os.pathsep``);
3. ``./scenes`` (relative to the working directory);
4. ``<repo root>/../shared/scenes`` if it exists: a convenience for this project's checkouts, which keep
   the shared test scenes beside the repository (never copied into it). Only when the package runs
   from a source checkout (the repo root has a ``pyproject.toml``).

In each folder a name ``foo`` matches ``foo.glb``, ``foo.gltf``, ``foo.obj``, ``foo.ply`` (in that order).

Every file scene is configured by its sidecar ``foo.probeplace.yaml`` when one lies beside it, under the
caller's ``overrides`` and over :data:`KNOWN_SCENES` (:mod:`.config._sidecar`).
"""

from __future__ import annotations

import dataclasses
import logging
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .._core import Scene, SceneError
from ._build import build_scene, make_materials
from ._raw import RawScene, ensure_views
from ._search import SCENE_EXTENSIONS, SCENE_PATH_ENV, find_scene_file, looks_like_path, scene_search_path
from .builtin import BUILTIN_SCENES
from .config import (
    KNOWN_SCENES,
    SceneConfig,
    apply_scene_config,
    check_layer,
    merge_scene_configs,
    no_light_hint,
    parse_scene_config,
    read_sidecar,
)
from .files import load_gltf, load_obj, load_ply

log = logging.getLogger(__name__)

_LOADERS = {".glb": load_gltf, ".gltf": load_gltf, ".obj": load_obj, ".ply": load_ply}


def load_scene(
    name_or_path: str | os.PathLike,
    *,
    search_path=None,
    overrides: Mapping | SceneConfig | None = None,
    sidecar: bool = True,
    require_light: bool | str = False,
) -> Scene:
    """Load a scene: a built-in by name, a file by path, or an external scene by name on the search path.

    A string with a path separator or a file extension (or any ``os.PathLike``) is a path; otherwise it
    is a name, and a built-in wins over a file of that name (load such a file by its path).

    Args:
        name_or_path: ``"temple"``, ``"crytek_sponza"``, ``"/data/my_scene.glb"``, ...
        search_path: extra folders searched first (see :func:`scene_search_path`).
        overrides: sidecar keys (docs/scenes.md, "Sidecar config") that win over the file's sidecar,
            e.g. ``scene_overrides(sun="az=120,el=35")`` from the CLI; also applied to built-ins.
        sidecar: read ``<stem>.probeplace.yaml`` beside a scene file (False: ignore it).
        require_light: refuse a scene with no light (an emitter, a sun or a sky) instead of warning; a
            string names what needs the light in the message (``"vardis placement"``).

    Returns:
        The validated Scene, with lights, sky, units and at least two views (a file keeps its cameras,
        or those of its sidecar / :data:`KNOWN_SCENES`, topped up with views derived from the bounds).

    Raises:
        SceneError: missing file, unsupported extension, unreadable or corrupt file, no triangles,
            non-finite vertices, a name that is neither built-in nor found (the message lists where
            it looked), or no light with ``require_light``.
        ConfigError: an invalid sidecar or ``overrides`` (the message names the file and key); the
            sidecar and ``overrides`` are read and checked before the scene file.
    """
    if looks_like_path(name_or_path):
        return load_scene_file(
            Path(name_or_path), overrides=overrides, sidecar=sidecar, require_light=require_light
        )
    name = str(name_or_path)
    if name in BUILTIN_SCENES:
        cfg = parse_scene_config(overrides, "overrides")
        scene = BUILTIN_SCENES[name]()
        if overrides:
            check_layer(cfg, set(scene.materials.names), scene.part_names, cfg.up_axis)
            scene = apply_scene_config(scene, cfg)
        return _light_check(scene, name, require_light, hint_path=None)
    path = find_scene_file(name, search_path)
    if path is None:
        dirs = "\n  ".join(str(d) for d in scene_search_path(search_path))
        raise SceneError(
            f"unknown scene {name!r}: not built-in ({', '.join(BUILTIN_SCENES)}) and no "
            f"{name}{{{','.join(SCENE_EXTENSIONS)}}} in the search path:\n  {dirs}\n"
            f"(add folders with search_path= or ${SCENE_PATH_ENV})"
        )
    return load_scene_file(path, overrides=overrides, sidecar=sidecar, require_light=require_light)


def _light_check(scene: Scene, source, require_light: bool | str, hint_path) -> Scene:
    if not scene.has_light:
        # a string says who needs the light (``place --method vardis``), so the refusal names it
        who = f", which {require_light} needs" if isinstance(require_light, str) else ""
        msg = (
            f"{source}: the scene has no light (no emissive material, sun or sky){who}; "
            f"{no_light_hint(hint_path)}"
        )
        if require_light:
            raise SceneError(msg)
        log.warning("%s", msg)
    return scene


def scene_config_layers(
    path: str | os.PathLike, overrides: Mapping | SceneConfig | None = None, sidecar: bool = True
) -> list[SceneConfig]:
    """The config layers of scene file ``path``, lowest precedence first: :data:`KNOWN_SCENES` for its
    stem, its sidecar, ``overrides`` (absent ones left out). Cheap: reads no scene geometry.

    Raises:
        ConfigError: an invalid sidecar or ``overrides``.
    """
    path = Path(path)
    known = KNOWN_SCENES.get(path.stem)
    layers = [
        parse_scene_config(known, f"KNOWN_SCENES[{path.stem!r}]") if known is not None else None,
        read_sidecar(path) if sidecar else None,
        parse_scene_config(overrides, "overrides") if overrides else None,
    ]
    return [layer for layer in layers if layer is not None]


def scene_layers(name_or_path, overrides=None) -> tuple[Path | None, list[SceneConfig]]:
    """What ``load_scene(name_or_path, overrides=overrides)`` reads besides geometry, cheaply: the scene
    file (``None`` for a built-in) and its config layers, lowest first (``scene_config_layers``). For
    messages that must name the layer a value came from (a camera's sidecar, say) after the load.

    Raises:
        ConfigError: an invalid sidecar or ``overrides`` (the load has refused them already).
    """
    if looks_like_path(name_or_path):
        path = Path(name_or_path)
    elif str(name_or_path) in BUILTIN_SCENES:
        path = None
    else:
        path = find_scene_file(str(name_or_path))
    if path is None:
        return None, [parse_scene_config(overrides, "overrides")] if overrides else []
    return path, scene_config_layers(path, overrides)


def load_scene_file(
    path: Path,
    *,
    overrides: Mapping | SceneConfig | None = None,
    sidecar: bool = True,
    require_light: bool | str = False,
) -> Scene:
    """Load one scene file (glTF/GLB, OBJ+MTL, PLY) and apply its config layers (:func:`load_scene`)."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in _LOADERS:
        raise SceneError(
            f"{path}: unsupported scene file extension {ext!r}; supported: {', '.join(SCENE_EXTENSIONS)}"
        )
    if not path.is_file():
        raise SceneError(f"{path}: scene file not found")
    layers = scene_config_layers(path, overrides, sidecar)  # before the (possibly slow) file read
    cfg = merge_scene_configs(*layers)
    raw: RawScene = _LOADERS[ext](path)
    names = set(raw.material_names)
    for layer in layers:
        names = check_layer(layer, names, raw.part_names, cfg.up_axis)
    materials = make_materials(raw.material_names, raw.base_color, raw.roughness, raw.metallic, raw.emission)
    scene = build_scene(
        path.stem,
        raw.vertices,
        raw.faces,
        raw.tri_material,
        materials,
        tri_part=raw.tri_part,
        part_names=raw.part_names,
        views=raw.views,
        sun=raw.sun,
        unit_m=raw.unit_m,
        source=str(path),
    )
    scene = apply_scene_config(scene, cfg)
    bounds = np.asarray(scene.bounds, np.float64)
    scene = dataclasses.replace(scene, views=tuple(ensure_views(list(scene.views), bounds)))
    return _light_check(scene, path, require_light, hint_path=path)
