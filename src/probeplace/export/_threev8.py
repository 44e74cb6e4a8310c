"""Three.V8 mixed-resolution probe grid ("LODProbeGrid", Yang 2023) — binary file plus JSON sidecar.

Yang 2023 ("Mixed-resolution Grid of Light Probes", §The Grid Structure) stores a grid as
``coverage_min``/``coverage_max`` (vec3), ``base_divisions`` (ivec3), ``sub_division_level`` (int),
``probe_data`` (10 × vec4 per probe: xyz = world position, w = resolution level, then 9 SH
coefficients in .xyz), a 16×16×2×16-bit DDGI-style visibility atlas, and the octree ``index``:

* ``index`` starts with one entry per base cell (x fastest, then y, then z);
* a leaf entry ``index[i] < probe_count`` is the probe of that cell;
* an inner entry ``index[i] ≥ probe_count`` points at the 8 children stored from
  ``index[base_count + (index[i] − probe_count)·8]`` (child c = x + 2y + 4z), in BFS order.

The binary file follows Three.V8's ``LODProbeGridSaver`` (little-endian): coverage_min (3 f32),
coverage_max (3 f32), base_divisions (3 i32), sub_division_level, probe_count, index_count, vis_res,
pack_size, pack_res (i32 each), probe_data (probe_count·10·4 f32), index (i32), visibility
(pack_res² × 2 uint16: RG16 UNORM mean distance and its standard deviation, divided by the sidecar's
``visibility_max_distance``; tile of probe i at column i mod pack_size, row i div pack_size, each
vis_res² interior texels plus the one-texel border, probeplace's octahedral convention).

**From arbitrary positions to a grid.** The coverage box is the probes' bounding box with a margin,
split into cubic base cells (``base_cells`` along the longest axis). A cell holding more than one
probe is subdivided (Yang's rule of subdividing where the content differs between sub-cells, with
"content" = probes) down to the first level at which every probe has a cell of its own; each leaf's
probe keeps its *actual* position (Yang: "the actual positions of the probes are used … except for the
trilinear interpolation"). A leaf without a probe gets a filler probe at its centre whose SH is copied
from the nearest real probe (Yang's conversion copies SH from parent to children the same way). The
real probes come first, in their order; the sidecar lists the fillers, so :func:`read_threev8` returns
exactly the active probes (positions and SH bit for bit).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import struct
from collections import deque
from pathlib import Path

import numpy as np

from .._core.files._io import write_bytes_atomic, write_json_atomic
from ._data import ExportError, ExportProbes
from ._octa import resample_bordered
from ._sh import SH_CONVENTION

THREEV8_FORMAT = "probeplace.ThreeV8LODProbeGrid/1"
_HEADER = struct.Struct("<3f3f3i6i")


@dataclasses.dataclass(frozen=True, eq=False)
class LODProbeGrid:
    """The arrays of a Three.V8 mixed-resolution grid (see the module docstring)."""

    coverage_min: np.ndarray  # (3,) float32
    coverage_max: np.ndarray  # (3,) float32
    base_divisions: np.ndarray  # (3,) int32
    sub_division_level: int
    probe_data: np.ndarray  # (probe_count, 10, 4) float32
    index: np.ndarray  # (index_count,) int32
    vis_res: int
    pack_size: int
    pack_res: int
    visibility: np.ndarray  # (pack_res, pack_res, 2) uint16

    @property
    def probe_count(self) -> int:
        return len(self.probe_data)

    def probe_index_at(self, position: np.ndarray) -> int:
        """The probe whose cell contains ``position`` (Yang 2023 §Sampling the Grid, ``get_probe_idx``)."""
        lvl = self.sub_division_level
        div = self.base_divisions.astype(np.int64)
        size = self.coverage_max.astype(np.float64) - self.coverage_min
        ipos = np.floor((np.asarray(position, np.float64) - self.coverage_min) / size * (div << lvl))
        ipos = np.clip(ipos, 0, (div << lvl) - 1).astype(np.int64)
        base = ipos >> lvl
        node = int(base[0] + (base[1] + base[2] * div[1]) * div[0])
        n_base = int(np.prod(div))
        for level in range(lvl + 1):
            entry = int(self.index[node])
            if entry < self.probe_count:
                return entry
            bit = (ipos >> (lvl - level - 1)) & 1
            node = n_base + (entry - self.probe_count) * 8 + int(bit[0] + 2 * bit[1] + 4 * bit[2])
        raise ExportError("index traversal ran past the deepest level: corrupt grid")


def _cell_of(p: np.ndarray, cmin: np.ndarray, cmax: np.ndarray, div: np.ndarray, level: int) -> np.ndarray:
    n = div.astype(np.int64) << level
    ipos = np.floor((p - cmin) / (cmax - cmin) * n).astype(np.int64)
    return np.clip(ipos, 0, n - 1)


def build_lod_grid(
    positions: np.ndarray, *, base_cells: int = 2, max_level: int = 10
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, np.ndarray, np.ndarray, np.ndarray]:
    """Fit a mixed-resolution grid around ``positions`` (module docstring).

    Returns:
        coverage_min, coverage_max (float32), base_divisions (int32), sub_division_level,
        grid positions (n_grid, 3) float32 (the inputs first, then fillers), levels (n_grid,),
        index (int32).
    """
    pos = np.asarray(positions, np.float32)
    n = len(pos)
    if n == 0:
        raise ExportError("a Three.V8 grid needs at least one active probe")
    if base_cells < 1:
        raise ExportError(f"base_cells must be >= 1, got {base_cells}")
    p64 = pos.astype(np.float64)
    lo, hi = p64.min(0), p64.max(0)
    size = float((hi - lo).max()) or 1.0
    cell = size * 1.1 / base_cells  # 5 % margin each side along the longest axis
    div = np.maximum(1, np.ceil((hi - lo + 0.1 * size) / cell)).astype(np.int32)
    centre = 0.5 * (lo + hi)
    cmin = (centre - 0.5 * div * cell).astype(np.float32).astype(np.float64)
    cmax = (centre + 0.5 * div * cell).astype(np.float32).astype(np.float64)
    level = 0
    while True:
        cells = _cell_of(p64, cmin, cmax, div, level)
        if len(np.unique(cells, axis=0)) == n:
            break
        level += 1
        if level > max_level:
            raise ExportError(
                f"probes are too close to give each its own cell within {max_level} subdivision levels "
                "(duplicate positions?)"
            )
    finest = _cell_of(p64, cmin, cmax, div, level)
    grid_pos: list[np.ndarray] = list(pos)
    levels: list[int] = [0] * n
    base_count = int(np.prod(div))
    index: list = [None] * base_count
    queue: deque = deque()
    for z in range(div[2]):
        for y in range(div[1]):
            for x in range(div[0]):
                members = np.flatnonzero(np.all((finest >> level) == (x, y, z), axis=1))
                queue.append((x + (y + z * int(div[1])) * int(div[0]), 0, np.array([x, y, z]), members))
    n_divided = 0
    span = cmax - cmin
    while queue:
        slot, lvl, ipos, members = queue.popleft()
        if len(members) <= 1:
            if len(members) == 1:
                index[slot] = int(members[0])
                levels[int(members[0])] = lvl
            else:  # an empty leaf: a filler probe at the cell centre
                centre_c = cmin + span * (ipos + 0.5) / (div.astype(np.int64) << lvl)
                index[slot] = len(grid_pos)
                grid_pos.append(centre_c.astype(np.float32))
                levels.append(lvl)
            continue
        index[slot] = ("node", n_divided)
        first = len(index)
        n_divided += 1
        index.extend([None] * 8)
        sub = finest[members] >> (level - lvl - 1)
        for c in range(8):
            d = np.array([c & 1, (c >> 1) & 1, (c >> 2) & 1])
            child = 2 * ipos + d
            queue.append((first + c, lvl + 1, child, members[np.all(sub == child, axis=1)]))
    count = len(grid_pos)
    flat = [count + v[1] if isinstance(v, tuple) else v for v in index]
    return (
        cmin.astype(np.float32),
        cmax.astype(np.float32),
        div,
        level,
        np.asarray(grid_pos, np.float32).reshape(-1, 3),
        np.asarray(levels, np.int32),
        np.asarray(flat, np.int32),
    )


def write_threev8(
    probes: ExportProbes, out: str | os.PathLike, *, base_cells: int = 2, vis_res: int = 16
) -> list[Path]:
    """Write ``out`` (binary, Three.V8 ``LODProbeGridSaver`` layout) and ``out + '.json'`` (sidecar).

    Active probes only. SH come from ``probes.sh`` (zeros when absent); the visibility atlas from the
    baked distance moments when ``probes.maps`` is set (else "unoccluded": mean = 1, deviation = 0).
    """
    out = Path(out)
    act = probes.active_only()
    cmin, cmax, div, level, gpos, levels, index = build_lod_grid(act.positions, base_cells=base_cells)
    n_src, n_grid = act.n, len(gpos)
    sh = np.zeros((n_grid, 9, 3), np.float32)
    if act.sh is not None:
        sh[:n_src] = act.sh
        if n_grid > n_src:  # fillers copy the SH of the nearest real probe
            d = np.linalg.norm(gpos[n_src:, None, :] - act.positions[None, :, :], axis=-1)
            sh[n_src:] = act.sh[np.argmin(d, axis=1)]
    pdata = np.zeros((n_grid, 10, 4), np.float32)
    pdata[:, 0, :3] = gpos
    pdata[:, 0, 3] = levels
    pdata[:, 1:, :3] = sh
    spacing = (cmax.astype(np.float64) - cmin) / div
    max_dist = float(np.linalg.norm(spacing))  # Three.V8's max_visibility: one base-cell diagonal
    pack_size = math.ceil(math.sqrt(n_grid))
    tile = vis_res + 2
    pack_res = pack_size * tile
    vis = np.zeros((pack_res, pack_res, 2), np.float32)
    tiles = np.zeros((n_grid, tile, tile, 2), np.float32)
    tiles[..., 0] = 1.0
    if act.maps is not None:
        mom = resample_bordered(act.maps.moments.astype(np.float64), vis_res)
        mean = mom[..., 0]
        std = np.sqrt(np.maximum(mom[..., 1] - mean * mean, 0.0))
        tiles[:n_src, ..., 0] = np.clip(mean / max_dist, 0.0, 1.0)
        tiles[:n_src, ..., 1] = np.clip(std / max_dist, 0.0, 1.0)
    for i in range(n_grid):
        r, c = divmod(i, pack_size)
        vis[r * tile : (r + 1) * tile, c * tile : (c + 1) * tile] = tiles[i]
    vis16 = np.round(vis * 65535.0).astype("<u2")
    header = _HEADER.pack(*cmin, *cmax, *div, level, n_grid, len(index), vis_res, pack_size, pack_res)
    blob = header + pdata.astype("<f4").tobytes() + index.astype("<i4").tobytes() + vis16.tobytes()
    sidecar = {
        "format": THREEV8_FORMAT,
        "binary": out.name,
        "layout": "Three.V8 LODProbeGridSaver (Yang 2023); see probeplace.export._threev8",
        "method": probes.method,
        "config": probes.metadata,
        "units_m": probes.units_m,
        "up_axis": "+Y",
        "handedness": "right",
        "source_count": n_src,
        "source_rows": np.flatnonzero(probes.active).tolist(),
        "filler_count": n_grid - n_src,
        "has_sh": act.sh is not None,
        "sh_convention": SH_CONVENTION,
        "visibility_max_distance": max_dist,
        "visibility_from_bake": act.maps is not None,
    }
    if act.inside is not None:
        sidecar["inside"] = act.inside.tolist()
    return [write_bytes_atomic(out, blob), write_json_atomic(f"{out}.json", sidecar)]


def read_lod_grid(path: str | os.PathLike) -> LODProbeGrid:
    """Parse the binary file (no sidecar needed)."""
    path = Path(path)
    data = path.read_bytes()
    if len(data) < _HEADER.size:
        raise ExportError(f"{path}: too short for a Three.V8 LODProbeGrid header")
    h = _HEADER.unpack_from(data, 0)
    cmin, cmax, div = np.array(h[0:3], np.float32), np.array(h[3:6], np.float32), np.array(h[6:9], np.int32)
    level, n, n_index, vis_res, pack_size, pack_res = h[9:15]
    sizes = (n * 40 * 4, n_index * 4, pack_res * pack_res * 2 * 2)
    if min(h[6:15]) < 0 or len(data) != _HEADER.size + sum(sizes) or (div <= 0).any():
        raise ExportError(f"{path}: header does not match the file size; not a LODProbeGrid file")
    off = _HEADER.size
    pdata = np.frombuffer(data, "<f4", n * 40, off).reshape(n, 10, 4).astype(np.float32)
    off += sizes[0]
    index = np.frombuffer(data, "<i4", n_index, off).astype(np.int32)
    off += sizes[1]
    vis = np.frombuffer(data, "<u2", pack_res * pack_res * 2, off).reshape(pack_res, pack_res, 2).copy()
    return LODProbeGrid(cmin, cmax, div, level, pdata, index, vis_res, pack_size, pack_res, vis)


def read_threev8(path: str | os.PathLike) -> ExportProbes:
    """Load probes from a Three.V8 grid; with the sidecar (``<path>.json``) the fillers are dropped and
    the result is exactly the exported active probes (lossless), else every grid probe is returned."""
    path = Path(path)
    grid = read_lod_grid(path)
    side_path = Path(f"{path}.json")
    side: dict = {}
    if side_path.is_file():
        try:
            side = json.loads(side_path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            raise ExportError(f"{side_path}: not valid JSON ({e})") from None
        if side.get("format") != THREEV8_FORMAT:
            raise ExportError(f"{side_path}: not a probeplace Three.V8 sidecar")
    n = int(side.get("source_count", grid.probe_count))
    if n > grid.probe_count:
        raise ExportError(f"{side_path}: sidecar lists {n} probes, the grid holds {grid.probe_count}")
    has_sh = bool(side.get("has_sh", True))
    return ExportProbes(
        positions=grid.probe_data[:n, 0, :3],
        active=np.ones(n, bool),
        method=str(side.get("method", "three.v8")),
        units_m=float(side.get("units_m", 1.0)),
        metadata=dict(side.get("config") or {}),
        sh=grid.probe_data[:n, 1:, :3] if has_sh else None,
        inside=np.asarray(side["inside"], bool) if "inside" in side else None,
    )
