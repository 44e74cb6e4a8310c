"""Mixed-resolution probe grid (Yang 2023, "Mixed-resolution Grid of Light Probes", Three.V8).

Construction (Yang 2023 §Constructing the Grid):

1. The coverage box is split into ``base_divisions`` cells; the *logical* (finest) resolution is
   ``base_divisions · 2^sub_division_level``.
2. "Voxelization" at the finest resolution: for each finest cell and axis a, a bit says whether a
   triangle lies between the cell's centre and the centre of its −a neighbour. Yang rasterises the
   triangles along each axis with the depth rounded to the nearest cell boundary, which is exactly a
   segment test between the two centres; we cast those segments as occlusion rays
   (:func:`probeplace.geometry.make_caster`, batched).
3. A cell of level ``L < sub_division_level`` is subdivided iff some set bit of a finest voxel inside it
   joins two finest sub-cells of *that* cell: along axis a, the voxel coordinate has a non-zero bit among
   its ``sub_division_level − L`` least significant bits ("there are some pairs of sub-cells located at
   two different sides of some triangle faces"). Parents of subdivided cells are subdivided (implied by
   the rule, enforced anyway).
4. BFS over the cells, filling ``positions`` (probes at cell centres, level per probe) and ``index``.

The ``index`` array (Yang 2023 §The Grid Structure): one entry per base cell first (x fastest, then y,
then z); a leaf entry ``index[i] < probe_count`` is its probe; an inner entry ``index[i] ≥ probe_count``
points at its 8 children stored from ``index[base_count + (index[i] − probe_count)·8]``, child
``c = x + 2y + 4z`` (the bits of the child's logical coordinate). Inner nodes are numbered and probes
assigned in BFS order. This is the layout of :mod:`probeplace.export._threev8` (``LODProbeGrid``), whose
``probe_index_at`` traverses our arrays unchanged (tested).

Lookup (Yang 2023 §Sampling the Grid, ``get_probe_idx``): the logical cell ``ipos`` of a point; start at
base cell ``ipos >> sub_division_level``; at each inner node descend to child
``bit_x + 2·bit_y + 4·bit_z`` of ``ipos >> (sub_division_level − level − 1)``.

Conversion to a uniform grid (Yang 2023 §Conversion to Uniform Grid): :meth:`LODGrid.uniform_indices`
gives, for every logical cell, the probe whose leaf contains it — duplicating a coarse probe's values to
its logical cells is safe "because there is no geometry in between"; visibility must be rebuilt at the
logical positions of cells whose leaf is coarser than the finest level (:meth:`LODGrid.uniform_positions`
and the mask from :meth:`LODGrid.uniform_levels`).
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from ..._core import ConfigError, ProbeSet, Scene, scene_box
from ...geometry import AbstractRayCaster, make_caster


@dataclasses.dataclass(frozen=True, eq=False)
class LODGrid:
    """A mixed-resolution probe grid (module docstring for the layout).

    Attributes:
        coverage_min: (3,) float32.
        coverage_max: (3,) float32.
        base_divisions: (3,) int32.
        sub_division_level: maximum subdivision level.
        positions: (probe_count, 3) float32 probe positions (cell centres), BFS order.
        levels: (probe_count,) int32 resolution level of each probe.
        index: (index_count,) int32 octree index.
    """

    coverage_min: np.ndarray
    coverage_max: np.ndarray
    base_divisions: np.ndarray
    sub_division_level: int
    positions: np.ndarray
    levels: np.ndarray
    index: np.ndarray

    @property
    def probe_count(self) -> int:
        return len(self.positions)

    @property
    def logical_dims(self) -> np.ndarray:
        """The logical (finest) resolution ``base_divisions · 2^sub_division_level``."""
        return self.base_divisions.astype(np.int64) << self.sub_division_level

    def logical_cells(self, points: np.ndarray) -> np.ndarray:
        """Logical cell coordinates (n, 3) int64 of points (clamped to the grid)."""
        n = self.logical_dims
        lo = self.coverage_min.astype(np.float64)
        size = self.coverage_max.astype(np.float64) - lo
        ipos = np.floor((np.asarray(points, np.float64).reshape(-1, 3) - lo) / size * n)
        return np.clip(ipos, 0, n - 1).astype(np.int64)

    def probe_indices_at(self, points: np.ndarray) -> np.ndarray:
        """Probe of the leaf cell containing each point, (n,) int64 (Yang's ``get_probe_idx``, batched)."""
        return self.probe_indices_of_cells(self.logical_cells(points))

    def probe_indices_of_cells(self, ipos: np.ndarray) -> np.ndarray:
        """Probe of the leaf containing each logical cell ``ipos`` (n, 3) (module docstring, Lookup)."""
        lvl = self.sub_division_level
        div = self.base_divisions.astype(np.int64)
        ipos = np.asarray(ipos, np.int64).reshape(-1, 3)
        base = ipos >> lvl
        node = base[:, 0] + (base[:, 1] + base[:, 2] * div[1]) * div[0]
        n_base, count = int(np.prod(div)), self.probe_count
        entry = self.index[node].astype(np.int64)
        for level in range(lvl):
            inner = entry >= count
            if not inner.any():
                break
            bit = (ipos >> (lvl - level - 1)) & 1
            child = n_base + (entry - count) * 8 + bit[:, 0] + 2 * bit[:, 1] + 4 * bit[:, 2]
            entry = np.where(inner, self.index[np.where(inner, child, 0)], entry)
        if np.any(entry >= count):
            raise ConfigError("index traversal ran past the deepest level: corrupt LOD grid")
        return entry

    def uniform_indices(self) -> np.ndarray:
        """Probe index of every logical cell, shape ``logical_dims`` reversed (z, y, x) — the uniform-grid
        conversion (module docstring)."""
        n = self.logical_dims
        z, y, x = np.meshgrid(np.arange(n[2]), np.arange(n[1]), np.arange(n[0]), indexing="ij")
        ipos = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
        return self.probe_indices_of_cells(ipos).reshape(int(n[2]), int(n[1]), int(n[0]))

    def uniform_positions(self) -> np.ndarray:
        """Logical cell centres (n_z, n_y, n_x, 3) float32 (where converted probes need new visibility)."""
        n = self.logical_dims
        lo = self.coverage_min.astype(np.float64)
        size = self.coverage_max.astype(np.float64) - lo
        axes = [lo[a] + (np.arange(n[a]) + 0.5) * size[a] / n[a] for a in range(3)]
        z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
        return np.stack([x, y, z], axis=-1).astype(np.float32)

    def uniform_levels(self) -> np.ndarray:
        """Level of the leaf holding each logical cell (n_z, n_y, n_x); visibility can be copied where it
        equals ``sub_division_level`` and must be rebuilt elsewhere (Yang 2023 §Conversion)."""
        return self.levels[self.uniform_indices()]

    def leaf_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """World (lo, hi) box of each probe's leaf cell, (probe_count, 3) float64 each."""
        lo = self.coverage_min.astype(np.float64)
        size = self.coverage_max.astype(np.float64) - lo
        cell = size / (self.base_divisions.astype(np.float64)[None, :] * (2.0 ** self.levels[:, None]))
        centre = self.positions.astype(np.float64)
        return centre - 0.5 * cell, centre + 0.5 * cell

    def to_probe_set(self) -> ProbeSet:
        """All probes as a :class:`~probeplace._core.ProbeSet` (``method="lod_grid"``)."""
        pos = jnp.asarray(self.positions, jnp.float32)
        return ProbeSet(pos, jnp.ones(len(self.positions), bool), method="lod_grid")


def _cell_centres(lo: np.ndarray, size: np.ndarray, n: np.ndarray, ipos: np.ndarray) -> np.ndarray:
    return lo + (ipos + 0.5) * size / n


def crossing_bits(
    caster: AbstractRayCaster,
    lo: np.ndarray,
    hi: np.ndarray,
    logical: np.ndarray,
    sub_division_level: int,
    *,
    chunk: int = 1 << 18,
) -> np.ndarray:
    """Yang's voxelization: (3, n_z, n_y, n_x) bool, axis a set where a triangle crosses the segment from
    the cell's −a neighbour's centre to its centre. Only segments inside a base cell are cast (the others
    never decide a subdivision)."""
    n = np.asarray(logical, np.int64)
    size = hi - lo
    step = size / n
    mask = (1 << sub_division_level) - 1
    bits = np.zeros((3, int(n[2]), int(n[1]), int(n[0])), bool)
    z, y, x = np.meshgrid(np.arange(n[2]), np.arange(n[1]), np.arange(n[0]), indexing="ij")
    ipos = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    for a in range(3):
        sel = np.flatnonzero((ipos[:, a] & mask) != 0)
        if len(sel) == 0:
            continue
        prev = ipos[sel].copy()
        prev[:, a] -= 1
        orig = _cell_centres(lo, size, n, prev).astype(np.float32)
        d = np.zeros_like(orig)
        d[:, a] = 1.0
        hit = np.zeros(len(sel), bool)
        for s in range(0, len(sel), chunk):
            hit[s : s + chunk] = caster.occluded_host(orig[s : s + chunk], d[s : s + chunk], float(step[a]))
        bits[a].reshape(-1)[sel] = hit
    return bits


def subdivision_masks(bits: np.ndarray, sub_division_level: int) -> list[np.ndarray]:
    """Per level L < sub_division_level, which level-L cells are subdivided, (n_z, n_y, n_x) at that level
    (module docstring, step 3)."""
    lvl = sub_division_level
    _, nz, ny, nx = bits.shape
    coords = (np.arange(nz)[:, None, None], np.arange(ny)[None, :, None], np.arange(nx)[None, None, :])
    masks = []
    for level in range(lvl):
        low = (1 << (lvl - level)) - 1
        internal = (
            (bits[0] & ((coords[2] & low) != 0))
            | (bits[1] & ((coords[1] & low) != 0))
            | (bits[2] & ((coords[0] & low) != 0))
        )
        f = 1 << (lvl - level)
        masks.append(internal.reshape(nz // f, f, ny // f, f, nx // f, f).any(axis=(1, 3, 5)))
    for level in range(lvl - 1, 0, -1):  # parents of subdivided cells are subdivided
        m = masks[level]
        z, y, x = m.shape
        masks[level - 1] |= m.reshape(z // 2, 2, y // 2, 2, x // 2, 2).any(axis=(1, 3, 5))
    return masks


def assemble_lod_grid(
    lo: np.ndarray,
    hi: np.ndarray,
    base_divisions: np.ndarray,
    sub_division_level: int,
    masks: list[np.ndarray],
) -> LODGrid:
    """BFS over the subdivision masks into Yang's (positions, levels, index) (module docstring, step 4)."""
    div = np.asarray(base_divisions, np.int64)
    z, y, x = np.meshgrid(np.arange(div[2]), np.arange(div[1]), np.arange(div[0]), indexing="ij")
    nodes = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)  # level-0 nodes in slot order
    size = hi - lo
    children = np.array([[c & 1, (c >> 1) & 1, (c >> 2) & 1] for c in range(8)], np.int64)
    per_level = []  # (split flags, nodes) per level, slots in BFS order
    for level in range(sub_division_level + 1):
        if level < sub_division_level:
            split = masks[level][nodes[:, 2], nodes[:, 1], nodes[:, 0]]
        else:
            split = np.zeros(len(nodes), bool)
        per_level.append((split, nodes))
        inner = nodes[split]
        nodes = (2 * inner[:, None, :] + children[None, :, :]).reshape(-1, 3)
    probe_count = sum(int((~s).sum()) for s, _ in per_level)
    index, positions, levels = [], [], []
    n_probe = n_inner = 0
    for level, (split, nodes) in enumerate(per_level):
        entry = np.empty(len(nodes), np.int64)
        n_leaf = int((~split).sum())
        entry[~split] = n_probe + np.arange(n_leaf)
        entry[split] = probe_count + n_inner + np.arange(int(split.sum()))
        n_probe += n_leaf
        n_inner += int(split.sum())
        index.append(entry)
        positions.append(_cell_centres(lo, size, div << level, nodes[~split]))
        levels.append(np.full(n_leaf, level, np.int32))
    return LODGrid(
        coverage_min=lo.astype(np.float32),
        coverage_max=hi.astype(np.float32),
        base_divisions=div.astype(np.int32),
        sub_division_level=int(sub_division_level),
        positions=np.concatenate(positions).astype(np.float32).reshape(-1, 3),
        levels=np.concatenate(levels),
        index=np.concatenate(index).astype(np.int32),
    )


def lod_probe_grid(
    scene: Scene,
    *,
    base_divisions=(5, 3, 3),
    sub_division_level: int = 3,
    bounds: tuple[np.ndarray, np.ndarray] | None = None,
    caster: AbstractRayCaster | None = None,
) -> LODGrid:
    """Build Yang's mixed-resolution grid for ``scene`` (module docstring).

    Args:
        scene: the scene (triangles only).
        base_divisions: base cells per axis (3 ints ≥ 1).
        sub_division_level: maximum subdivision level (≥ 0).
        bounds: (lo, hi) coverage box; default the scene's bounding box.
        caster: segment-test caster; default ``make_caster(scene)``.

    Returns:
        The grid.

    Raises:
        ConfigError: bad divisions, level or bounds.
    """
    div = np.asarray(base_divisions)
    if div.shape != (3,) or not np.issubdtype(div.dtype, np.integer) or div.min() < 1:
        raise ConfigError(f"base_divisions must be 3 integers ≥ 1, got {base_divisions}")
    lvl = int(sub_division_level)
    if lvl < 0 or lvl != sub_division_level or lvl > 10:
        raise ConfigError(f"sub_division_level must be an integer in [0, 10], got {sub_division_level}")
    logical = div.astype(np.int64) << lvl
    if int(np.prod(logical)) > 1 << 27:
        raise ConfigError(f"logical resolution {logical.tolist()} is too large (over 2^27 cells)")
    lo, hi = scene_box(scene, bounds)
    if not np.all(hi > lo):  # a flat scene's own box
        raise ConfigError(f"coverage box needs hi > lo per axis, got {lo} and {hi}")
    # round through float32 once so the stored box and the construction agree
    lo, hi = lo.astype(np.float32).astype(np.float64), hi.astype(np.float32).astype(np.float64)
    caster = make_caster(scene) if caster is None else caster
    bits = crossing_bits(caster, lo, hi, logical, lvl)
    return assemble_lod_grid(lo, hi, div, lvl, subdivision_masks(bits, lvl))
