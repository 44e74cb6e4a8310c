"""What a file loader hands to :func:`~probeplace.scene.load_scene`: numpy triangles per part, a material
table and whatever views the file holds. Also the rule for views derived from the bounds."""

from __future__ import annotations

import dataclasses
import logging
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .._core import Camera, SceneError, Sun
from ._build import make_camera

log = logging.getLogger(__name__)

#: Material given to geometry whose file says nothing about its look (PLY, OBJ without MTL).
DEFAULT_GREY = (0.6, 0.6, 0.6)


@dataclasses.dataclass
class RawScene:
    """Loader output, host-side numpy (validated later by :func:`~probeplace.scene.build_scene`).

    Attributes:
        vertices: (n_vert, 3) positions, file units, world frame (node transforms applied).
        faces: (n_tri, 3) vertex indices.
        tri_material: (n_tri,) row of the material arrays.
        tri_part: (n_tri,) index into ``part_names``.
        part_names: one name per part.
        material_names: one name per material row.
        base_color, roughness, metallic, emission: material arrays, shapes (n_mat, 3), (n_mat,),
            (n_mat,), (n_mat, 3).
        views: cameras the file defines (may be empty).
        sun: the sun the file defines (glTF ``KHR_lights_punctual`` directional light), or None.
        unit_m: metres per file unit, if the file says (glTF: 1 by specification).
    """

    vertices: np.ndarray
    faces: np.ndarray
    tri_material: np.ndarray
    tri_part: np.ndarray
    part_names: list[str]
    material_names: list[str]
    base_color: np.ndarray
    roughness: np.ndarray
    metallic: np.ndarray
    emission: np.ndarray
    views: list[Camera] = dataclasses.field(default_factory=list)
    unit_m: float = 1.0
    sun: Sun | None = None


class PartCollector:
    """Accumulates (vertices, faces, material row) per part while a loader walks a file."""

    def __init__(self) -> None:
        self.verts: list[np.ndarray] = []
        self.faces: list[np.ndarray] = []
        self.mat: list[np.ndarray] = []
        self.part: list[np.ndarray] = []
        self.part_names: list[str] = []
        self._n = 0

    def add(self, name: str, vertices: np.ndarray, faces: np.ndarray, material: int) -> None:
        faces = np.asarray(faces, np.int64).reshape(-1, 3)
        if len(faces) == 0:
            return
        unique = name
        k = 1
        while unique in self.part_names:  # two nodes with one name stay two parts
            unique, k = f"{name}_{k}", k + 1
        self.part_names.append(unique)
        self.verts.append(np.asarray(vertices, np.float64).reshape(-1, 3))
        self.faces.append(faces + self._n)
        self.mat.append(np.full(len(faces), material, np.int64))
        self.part.append(np.full(len(faces), len(self.part_names) - 1, np.int64))
        self._n += len(vertices)

    def arrays(self, source: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        if not self.faces:
            raise SceneError(f"{source}: the file contains no triangles")
        return (
            np.concatenate(self.verts),
            np.concatenate(self.faces),
            np.concatenate(self.mat),
            np.concatenate(self.part),
        )


@contextmanager
def trimesh_errors(path: Path, what: str) -> Iterator[None]:
    """Turn anything trimesh raises while reading ``path`` into a SceneError naming the file, and its
    warnings into log records (they describe the file, not our code)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            yield
        except SceneError:
            raise
        except Exception as e:  # trimesh raises many types (ValueError, KeyError, struct.error, ...)
            raise SceneError(f"{path}: could not read the {what} file ({type(e).__name__}: {e})") from e
    for w in caught:
        log.warning("%s: trimesh: %s", path, w.message)


def derived_views(bounds: np.ndarray, fov_y_deg: float = 60.0) -> list[Camera]:
    """Two views derived from the scene bounds, for files that define no cameras.

    Rule (+Y up; ``a`` is the longer horizontal axis, ``b`` the shorter; ``e`` the extents):

    * ``long_axis``: from inside the box 15% of the way along ``a``, centred on ``b``, at 30% of the
      height, looking straight along ``a`` to the point 85% of the way along it.
    * ``overview``: from 20% along ``a`` and ``b`` at 75% of the height, looking down at the centre of
      the box at 25% of the height.

    Both positions are strictly inside the bounds; whether they are in free space (not inside a wall)
    depends on the scene, so scenes we know get explicit views (:mod:`~probeplace.scene.config._known`).
    """
    lo, hi = np.asarray(bounds[0], np.float64), np.asarray(bounds[1], np.float64)
    e = hi - lo
    a, b = (0, 2) if e[0] >= e[2] else (2, 0)

    def point(fa: float, fy: float, fb: float) -> np.ndarray:
        p = np.empty(3)
        p[a], p[1], p[b] = lo[a] + fa * e[a], lo[1] + fy * e[1], lo[b] + fb * e[b]
        return p

    return [
        make_camera(point(0.15, 0.3, 0.5), point(0.85, 0.3, 0.5), fov_y_deg, "long_axis"),
        make_camera(point(0.2, 0.75, 0.2), point(0.5, 0.25, 0.5), fov_y_deg, "overview"),
    ]


def ensure_views(
    views: list[Camera], bounds: np.ndarray, derive: Callable[[np.ndarray], list[Camera]] = derived_views
) -> list[Camera]:
    """``views`` topped up with derived views (names not already taken) until there are at least two."""
    out = list(views)
    taken = {v.name for v in out}
    for v in derive(bounds):
        if len(out) >= 2:
            break
        if v.name not in taken:
            out.append(v)
    return out


def material_arrays(materials: list[dict]) -> dict[str, np.ndarray]:
    """The material arrays of :class:`RawScene` from one dict per material (``base_color``, ``roughness``,
    ``metallic``, ``emission``), as the file loaders collect them."""
    return {
        "base_color": np.stack([m["base_color"] for m in materials]),
        "roughness": np.array([m["roughness"] for m in materials]),
        "metallic": np.array([m["metallic"] for m in materials]),
        "emission": np.stack([m["emission"] for m in materials]),
    }
