"""Reachable free space: the part of the SDF's free space a viewer can get to.

A probe sealed off from the viewer — between Sponza's vaults and its roof, inside a closed void, in a
wall cavity wider than the clearance — holds light no view ever reads, and the bake's reach test
(``probes._inside``) disables it. The placement's valid space therefore excludes it up front, with the
voxel form of the same idea: the exterior flood fill of mesh repair (Ju 2004, "Robust repair of polygonal
models", SIGGRAPH), run on the SDF lattice.

* **Free lattice points**: SDF value ≥ the clearance. Beyond the SDF's exact band the stored values are
  lower bounds, so a free point is free for certain; the flood never crosses a wall, since every lattice
  point within the clearance of a surface is not free. Only the magnitude matters where the SDF's sign is
  wrong (open, inconsistently wound meshes), because a surface's neighbourhood blocks the flood either way.
* **Components**: 6-connected components of the free points (``scipy.ndimage.label``).
* **Seeds**: the free lattice point nearest each view camera (the viewer is where the views are). A scene
  without views gets no constraint (``None``): its lattice's boundary is free space outside the scene box
  for an open and a closed scene alike, so nothing tells a room from a sealed void there.
* A point is reachable when a free corner of its lattice cell is in a seeded component. A point whose
  trilinear SDF is ≥ the clearance has a free corner (the value is a convex combination of the corners').
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from ..._core import Scene
from ...geometry import SDFGrid


@dataclasses.dataclass(frozen=True, eq=False)
class ReachableSpace:
    """The reachable free lattice points of one SDF at one clearance.

    Attributes:
        mask: (nx, ny, nz) bool, reachable free lattice points.
        origin: world position of lattice point (0, 0, 0).
        voxel_size: lattice spacing.
    """

    mask: np.ndarray
    origin: np.ndarray
    voxel_size: float

    def contains(self, pos: np.ndarray) -> np.ndarray:
        """(n,) bool: a corner of the point's lattice cell is reachable (points outside the lattice are
        clamped to it)."""
        p = (np.asarray(pos, np.float64).reshape(-1, 3) - self.origin) / self.voxel_size
        shape = np.array(self.mask.shape)
        i0 = np.clip(np.floor(p).astype(np.int64), 0, shape - 2)
        out = np.zeros(len(p), bool)
        for corner in np.ndindex(2, 2, 2):
            i = i0 + np.array(corner)
            out |= self.mask[i[:, 0], i[:, 1], i[:, 2]]
        return out

    def points(self) -> np.ndarray:
        """(m, 3) float64 world positions of the reachable lattice points."""
        return self.origin + np.argwhere(self.mask) * self.voxel_size

    def record(self) -> dict:
        return {"reachable_points": int(self.mask.sum()), "free_share": float(self.mask.mean())}


def view_positions(scene: Scene) -> np.ndarray:
    """(c, 3) float64 positions of ``scene``'s view cameras (c may be 0): the seeds of the reach."""
    return np.asarray([np.asarray(c.position, np.float64) for c in scene.views]).reshape(-1, 3)


def reachable_space(sdf: SDFGrid, clearance: float, cameras: np.ndarray) -> ReachableSpace | None:
    """The :class:`ReachableSpace` of ``sdf`` at ``clearance`` seeded by the ``cameras`` positions ((c, 3),
    usually :func:`view_positions`; module docstring); ``None`` when there is no camera or no lattice point
    is free. Cached per (SDF, clearance, cameras): placement asks for it at every validity check."""
    cams = tuple(map(tuple, np.asarray(cameras, np.float64).reshape(-1, 3)))
    return _reachable(_GridKey(sdf), float(clearance), cams)


class _GridKey:
    """Hashable by identity of the SDF's arrays (an SDFGrid is not hashable)."""

    def __init__(self, sdf: SDFGrid):
        self.sdf = sdf

    def __hash__(self) -> int:
        return hash((id(self.sdf.values), self.sdf.mesh_hash))

    def __eq__(self, other) -> bool:
        return isinstance(other, _GridKey) and other.sdf.values is self.sdf.values


@functools.lru_cache(maxsize=2)  # a Sponza lattice is ~100 MB: keep the last two
def _reachable(key: _GridKey, clearance: float, cams: tuple) -> ReachableSpace | None:
    from scipy import ndimage

    sdf = key.sdf
    values = np.asarray(sdf.values)
    origin = np.asarray(sdf.origin, np.float64)
    h = float(sdf.voxel_size)
    free = values >= clearance
    if not cams or not free.any():
        return None
    label, _ = ndimage.label(free)  # 6-connected
    # the nearest free lattice point of each camera: a camera may sit nearer a wall than the clearance
    _, nearest = ndimage.distance_transform_edt(~free, return_indices=True)
    idx = np.clip(np.rint((np.asarray(cams) - origin) / h).astype(np.int64), 0, np.array(free.shape) - 1)
    seed_labels = label[tuple(nearest[:, idx[:, 0], idx[:, 1], idx[:, 2]])]
    seed_labels = np.unique(seed_labels[seed_labels > 0])
    if not len(seed_labels):
        return None
    return ReachableSpace(np.isin(label, seed_labels), origin, h)
