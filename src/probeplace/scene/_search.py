"""Where scene names resolve (the search path of :mod:`._load`) and what ``list_scenes`` finds.

Plain Python, no JAX: ``probeplace scenes`` lists scenes through this module without loading any scene.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from pathlib import Path

from .builtin import BUILTIN_SCENES, builtin_scene_module
from .config import sidecar_path

#: Environment variable holding extra scene folders (``os.pathsep``-separated).
SCENE_PATH_ENV = "PROBEPLACE_SCENE_PATH"
#: Supported file extensions, in the order a bare name tries them.
SCENE_EXTENSIONS = (".glb", ".gltf", ".obj", ".ply")
# src/probeplace/scene/_search.py -> parents[3] is the checkout's root.
_REPO_ROOT = Path(__file__).resolve().parents[3]


@dataclasses.dataclass(frozen=True)
class SceneEntry:
    """One scene ``list_scenes`` found.

    Attributes:
        name: what to pass to :func:`load_scene`.
        kind: ``"builtin"`` or ``"file"``.
        source: the factory's module (built-ins) or the file's path.
        sidecar: the path of the file's sidecar config if it has one (:func:`sidecar_path`), else None.
    """

    name: str
    kind: str
    source: str
    sidecar: str | None = None


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
    out = [SceneEntry(n, "builtin", builtin_scene_module(n)) for n in BUILTIN_SCENES]
    seen: set[str] = set()
    for d in scene_search_path(search_path):
        if not d.is_dir():
            continue
        files = [p for p in d.iterdir() if p.is_file() and p.suffix.lower() in SCENE_EXTENSIONS]
        files.sort(key=lambda p: (p.stem, SCENE_EXTENSIONS.index(p.suffix.lower())))
        for p in files:
            if p.stem not in seen:
                seen.add(p.stem)
                side = sidecar_path(p)
                out.append(SceneEntry(p.stem, "file", str(p), str(side) if side.is_file() else None))
    return out


def looks_like_path(x: str | os.PathLike) -> bool:
    """Whether a scene argument names a file (a path object, a separator or a suffix) rather than a
    built-in or search-path scene name."""
    if isinstance(x, os.PathLike):
        return True
    return os.sep in x or (os.altsep is not None and os.altsep in x) or Path(x).suffix != ""
