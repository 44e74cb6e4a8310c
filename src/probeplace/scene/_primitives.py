"""Closed, outward-wound mesh primitives for the procedural scenes (numpy, float64, metres).

Every primitive returns ``(vertices, faces)``: ``vertices`` (n, 3) float64 and ``faces`` (m, 3) int64,
counter-clockwise seen from outside (so the right-hand normal points out of the solid, the convention of
:class:`~probeplace._core.Scene`). Boxes and cylinders are closed 2-manifolds (trimesh: watertight,
positive signed volume); a quad is a single-sided sheet.

:class:`MeshAssembler` collects primitives into parts with materials and hands them to
:func:`~probeplace.scene.build_scene`, which is how the built-in scenes are made.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._core import Camera, Materials, Scene, Sun
from ._build import build_scene

#: A 3-vector given as a tuple/list of numbers or an array of shape (3,).
Vec3Like = Sequence[float] | np.ndarray

# Corner k of a box is (x, y, z) with x = hi if bit 0 of k, y = hi if bit 1, z = hi if bit 2.
_BOX_QUADS = np.array(
    [
        [0, 4, 6, 2],  # -X face
        [1, 3, 7, 5],  # +X
        [0, 1, 5, 4],  # -Y
        [2, 6, 7, 3],  # +Y
        [0, 2, 3, 1],  # -Z
        [4, 5, 7, 6],  # +Z
    ]
)


#: Triangle indices of each face of :func:`box` (the two halves of each quad).
BOX_FACE_TRIS = {name: (q, q + 6) for q, name in enumerate(("-x", "+x", "-y", "+y", "-z", "+z"))}


def _quads_to_tris(quads: np.ndarray) -> np.ndarray:
    """Split quads (q, 4) into triangles (2q, 3) along the 0–2 diagonal, keeping the winding."""
    return np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]], axis=0)


def box(lo: Vec3Like, hi: Vec3Like) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned closed box with corners ``lo`` < ``hi`` (8 vertices, 12 triangles).

    Raises:
        ValueError: ``hi`` is not strictly greater than ``lo`` on every axis.
    """
    lo_a, hi_a = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    if lo_a.shape != (3,) or hi_a.shape != (3,) or not np.all(hi_a > lo_a):
        raise ValueError(f"box needs lo < hi on every axis, got lo={lo_a}, hi={hi_a}")
    k = np.arange(8)
    bits = np.stack([(k >> 0) & 1, (k >> 1) & 1, (k >> 2) & 1], axis=1).astype(bool)
    verts = np.where(bits, hi_a, lo_a)
    return verts, _quads_to_tris(_BOX_QUADS)


def cylinder(
    base_centre: Vec3Like, radius: float, height: float, n_segments: int = 24
) -> tuple[np.ndarray, np.ndarray]:
    """Closed upright cylinder (axis +Y) with flat caps, tessellated into ``n_segments`` sides.

    The side facets meet at 360°/n_segments < the 30° crease angle for n ≥ 13, so
    :func:`~probeplace.scene.crease_normals` smooths them into a round column while the caps stay flat.

    Returns 2n + 2 vertices and 4n triangles.
    """
    if radius <= 0 or height <= 0 or n_segments < 3:
        raise ValueError(
            f"cylinder needs radius, height > 0 and n_segments >= 3, got {radius}, {height}, {n_segments}"
        )
    c = np.asarray(base_centre, np.float64)
    ang = 2.0 * np.pi * np.arange(n_segments) / n_segments
    # Counter-clockwise seen from +Y is x = cos, z = -sin (right-handed, +Y up).
    ring = np.stack([radius * np.cos(ang), np.zeros(n_segments), -radius * np.sin(ang)], axis=1)
    lift = np.array([0.0, height, 0.0])
    verts = np.concatenate([c + ring, c + ring + lift, c[None], (c + lift)[None]])
    i = np.arange(n_segments)
    j = (i + 1) % n_segments
    n = n_segments
    side = _quads_to_tris(np.stack([i, j, n + j, n + i], axis=1))
    cap_bottom = np.stack([np.full(n, 2 * n), j, i], axis=1)  # seen from below: clockwise ring
    cap_top = np.stack([np.full(n, 2 * n + 1), n + i, n + j], axis=1)
    return verts, np.concatenate([side, cap_bottom, cap_top])


def quad(origin: Vec3Like, u: Vec3Like, v: Vec3Like) -> tuple[np.ndarray, np.ndarray]:
    """Single-sided parallelogram with corners origin, origin+u, origin+u+v, origin+v; its front
    (counter-clockwise) side faces along u × v. Not closed: use it only for emitters or thin decals."""
    o, uu, vv = (np.asarray(a, np.float64) for a in (origin, u, v))
    if np.linalg.norm(np.cross(uu, vv)) == 0:
        raise ValueError(f"quad edges must not be parallel, got u={uu}, v={vv}")
    return np.stack([o, o + uu, o + uu + vv, o + vv]), np.array([[0, 1, 2], [0, 2, 3]])


def rotation_y(angle_rad: float) -> np.ndarray:
    """3×3 rotation about +Y by ``angle_rad`` (right-handed: +X turns toward −Z)."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def place(
    mesh: tuple[np.ndarray, np.ndarray], rotation: np.ndarray | None = None, translation=(0.0, 0.0, 0.0)
) -> tuple[np.ndarray, np.ndarray]:
    """Rigidly move a primitive: x ↦ R x + t (a proper rotation keeps the winding outward)."""
    v, f = mesh
    if rotation is not None:
        v = v @ np.asarray(rotation, np.float64).T
    return v + np.asarray(translation, np.float64), f


class MeshAssembler:
    """Collects primitives into named parts with named materials, then builds a Scene.

    Host-side helper for the procedural scenes (mutable on purpose: it is a builder, not a pytree).
    """

    def __init__(self) -> None:
        self._verts: list[np.ndarray] = []
        self._faces: list[np.ndarray] = []
        self._mat: list[np.ndarray] = []
        self._part: list[np.ndarray] = []
        self._n_vert = 0
        self.part_names: list[str] = []
        self.material_names: list[str] = []

    def _index(self, names: list[str], name: str) -> int:
        if name not in names:
            names.append(name)
        return names.index(name)

    def add(
        self,
        mesh: tuple[np.ndarray, np.ndarray],
        material: str,
        part: str,
        face_materials: dict[int, str] | None = None,
    ) -> None:
        """Append ``mesh`` to ``part`` with ``material``; ``face_materials`` overrides single triangles
        (e.g. only the bottom of a light fixture emits)."""
        v, f = mesh
        mat = np.full(len(f), self._index(self.material_names, material), np.int64)
        for tri, name in (face_materials or {}).items():
            mat[tri] = self._index(self.material_names, name)
        self._verts.append(np.asarray(v, np.float64))
        self._faces.append(np.asarray(f, np.int64) + self._n_vert)
        self._mat.append(mat)
        self._part.append(np.full(len(f), self._index(self.part_names, part), np.int64))
        self._n_vert += len(v)

    @property
    def n_triangles(self) -> int:
        return int(sum(len(f) for f in self._faces))

    def build(
        self,
        name: str,
        materials: Materials,
        *,
        views: Sequence[Camera],
        sun: Sun | None = None,
        sky_radiance=(0.0, 0.0, 0.0),
    ) -> Scene:
        """Build the Scene; ``materials.names`` must list every material name used (any order)."""
        missing = set(self.material_names) - set(materials.names)
        if missing:
            raise ValueError(f"{name}: materials {sorted(missing)} are used but not defined")
        remap = np.array([materials.names.index(m) for m in self.material_names], np.int64)
        return build_scene(
            name,
            np.concatenate(self._verts),
            np.concatenate(self._faces),
            remap[np.concatenate(self._mat)],
            materials,
            tri_part=np.concatenate(self._part),
            part_names=tuple(self.part_names),
            views=views,
            sun=sun,
            sky_radiance=sky_radiance,
            unit_m=1.0,
            source=f"builtin:{name}",
        )
