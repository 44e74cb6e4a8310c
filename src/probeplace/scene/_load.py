"""``load_scene``: built-in scenes by name, scene files by path, external scenes by name on a search path.

Search path (first match wins), used for names that are not built-in:

1. the ``search_path`` argument (a sequence of folders, or one string of folders joined by ``os.pathsep``);
2. the environment variable ``PROBEPLACE_SCENE_PATH`` (folders joined by ``os.pathsep``);
3. ``./scenes`` (relative to the working directory);
4. ``<repo root>/../shared/scenes`` if it exists: a convenience for this project's checkouts, which keep
   the shared test scenes beside the repository (never copied into it). Only when the package runs
   from a source checkout (the repo root has a ``pyproject.toml``).

In each folder a name ``foo`` matches ``foo.glb``, ``foo.gltf``, ``foo.obj``, ``foo.ply`` (in that order).
"""

from __future__ import annotations

import dataclasses
import logging
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .._core import Scene, SceneError
from ._build import build_scene, make_materials
from ._gltf import load_gltf
from ._known import KNOWN_SCENES
from ._obj import load_obj
from ._ply import load_ply
from ._raw import RawScene, ensure_views
from ._registry import BUILTIN_SCENES

log = logging.getLogger(__name__)

#: Environment variable holding extra scene folders (``os.pathsep``-separated).
SCENE_PATH_ENV = "PROBEPLACE_SCENE_PATH"
#: Supported file extensions, in the order a bare name tries them.
SCENE_EXTENSIONS = (".glb", ".gltf", ".obj", ".ply")
_LOADERS = {".glb": load_gltf, ".gltf": load_gltf, ".obj": load_obj, ".ply": load_ply}
# src/probeplace/scene/_load.py -> parents[3] is the checkout's root.
_REPO_ROOT = Path(__file__).resolve().parents[3]


@dataclasses.dataclass(frozen=True)
class SceneEntry:
    """One scene ``list_scenes`` found.

    Attributes:
        name: what to pass to :func:`load_scene`.
        kind: ``"builtin"`` or ``"file"``.
        source: the factory's module (built-ins) or the file's path.
    """

    name: str
    kind: str
    source: str


def _split(value: str) -> list[Path]:
    return [Path(p) for p in value.split(os.pathsep) if p]


def scene_search_path(
    search_path: str | os.PathLike | Sequence[str | os.PathLike] | None = None,
) -> list[Path]:
    """The folders searched for scene names, in order (see the module docstring); missing ones included."""
    dirs: list[Path] = []
    if isinstance(search_path, str):
        dirs += _split(search_path)
    elif isinstance(search_path, os.PathLike):
        dirs.append(Path(search_path))
    elif search_path is not None:
        dirs += [Path(p) for p in search_path]
    dirs += _split(os.environ.get(SCENE_PATH_ENV, ""))
    dirs.append(Path("scenes"))
    shared = _REPO_ROOT.parent / "shared" / "scenes"
    if (_REPO_ROOT / "pyproject.toml").is_file() and shared.is_dir():
        dirs.append(shared)
    return dirs


def find_scene_file(name: str, search_path=None) -> Path | None:
    """First ``<dir>/<name><ext>`` on the search path, or None."""
    for d in scene_search_path(search_path):
        for ext in SCENE_EXTENSIONS:
            p = d / f"{name}{ext}"
            if p.is_file():
                return p
    return None


def list_scenes(search_path=None) -> list[SceneEntry]:
    """Built-in scenes, then every supported file on the search path (a name shadowed by an earlier
    folder, or by an earlier extension in the same folder, is listed once: the one a name resolves to).
    A file whose stem is a built-in's name is listed too, but loads only by path."""
    out = [SceneEntry(n, "builtin", f.__module__) for n, f in BUILTIN_SCENES.items()]
    seen: set[str] = set()
    for d in scene_search_path(search_path):
        if not d.is_dir():
            continue
        files = [p for p in d.iterdir() if p.is_file() and p.suffix.lower() in SCENE_EXTENSIONS]
        files.sort(key=lambda p: (p.stem, SCENE_EXTENSIONS.index(p.suffix.lower())))
        for p in files:
            if p.stem not in seen:
                seen.add(p.stem)
                out.append(SceneEntry(p.stem, "file", str(p)))
    return out


def _looks_like_path(x: str | os.PathLike) -> bool:
    if isinstance(x, os.PathLike):
        return True
    return os.sep in x or (os.altsep is not None and os.altsep in x) or Path(x).suffix != ""


def load_scene(name_or_path: str | os.PathLike, *, search_path=None) -> Scene:
    """Load a scene: a built-in by name, a file by path, or an external scene by name on the search path.

    A string with a path separator or a file extension (or any ``os.PathLike``) is a path; otherwise it
    is a name, and a built-in wins over a file of that name (load such a file by its path).

    Args:
        name_or_path: ``"temple"``, ``"crytek_sponza"``, ``"/data/my_scene.glb"``, ...
        search_path: extra folders searched first (see :func:`scene_search_path`).

    Returns:
        The validated Scene, with lights, sky, units and at least two views (known scenes get theirs
        from :mod:`~probeplace.scene._known`; others keep the file's cameras, topped up with views
        derived from the bounds).

    Raises:
        SceneError: missing file, unsupported extension, unreadable or corrupt file, no triangles,
            non-finite vertices, or a name that is neither built-in nor found (the message lists where
            it looked).
    """
    if _looks_like_path(name_or_path):
        return load_scene_file(Path(name_or_path))
    name = str(name_or_path)
    if name in BUILTIN_SCENES:
        return BUILTIN_SCENES[name]()
    path = find_scene_file(name, search_path)
    if path is None:
        dirs = "\n  ".join(str(d) for d in scene_search_path(search_path))
        raise SceneError(
            f"unknown scene {name!r}: not built-in ({', '.join(BUILTIN_SCENES)}) and no "
            f"{name}{{{','.join(SCENE_EXTENSIONS)}}} in the search path:\n  {dirs}\n"
            f"(add folders with search_path= or ${SCENE_PATH_ENV})"
        )
    return load_scene_file(path)


def load_scene_file(path: Path) -> Scene:
    """Load one scene file (glTF/GLB, OBJ+MTL, PLY), adding what :data:`KNOWN_SCENES` knows of it."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in _LOADERS:
        raise SceneError(
            f"{path}: unsupported scene file extension {ext!r}; supported: {', '.join(SCENE_EXTENSIONS)}"
        )
    if not path.is_file():
        raise SceneError(f"{path}: scene file not found")
    raw: RawScene = _LOADERS[ext](path)
    known = KNOWN_SCENES.get(path.stem)
    views = list(known.views()) if known is not None else raw.views
    finite = np.all(np.isfinite(raw.vertices), axis=1)
    bounds = (
        np.stack([raw.vertices[finite].min(0), raw.vertices[finite].max(0)])
        if finite.any()
        else np.zeros((2, 3))
    )
    views = ensure_views(views, bounds)
    unit_m = known.unit_m if known is not None and known.unit_m is not None else raw.unit_m
    materials = make_materials(raw.material_names, raw.base_color, raw.roughness, raw.metallic, raw.emission)
    scene = build_scene(
        path.stem,
        raw.vertices,
        raw.faces,
        raw.tri_material,
        materials,
        tri_part=raw.tri_part,
        part_names=raw.part_names,
        views=views,
        sun=known.sun() if known is not None and known.sun is not None else None,
        sky_radiance=known.sky_radiance if known is not None else (0.0, 0.0, 0.0),
        unit_m=unit_m,
        source=str(path),
    )
    if not scene.has_light:
        log.warning(
            "%s: the scene has no light (no emissive material, sun or sky); add one to render it", path
        )
    return scene
