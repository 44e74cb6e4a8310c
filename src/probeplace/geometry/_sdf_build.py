"""Build an :class:`SDFGrid` from a scene: resolution, exact band, conservative far field, sign, disk cache.

Pipeline (host; timings for Crytek Sponza, 262k triangles, h = 0.127, 18.3M voxels, in docs/sdf.md):

1. resolution h from the scene's extent and thinnest solids (:func:`default_voxel_size`), refused with a
   :class:`ResourceError` when the build would need more than ``MAX_BUILD_BYTES``;
2. side labels per connected component from generalized winding numbers (:mod:`._sdf_sign`);
3. exact distances within ``band`` voxels of a triangle by rasterization (:mod:`._sdf_raster`);
4. beyond the band, a lower bound: the largest of band·h, max_c (D_c − |p − c|) over the 8 corners c of
   p's cell in a coarse lattice (spacing k·h) whose distances D_c are exact (libigl AABB), and
   e(p) + (band − √3)·h with e the (chessboard) distance to the band. All are valid lower bounds (a voxel
   outside the band has distance > band·h; the distance is 1-Lipschitz), so sphere tracing never
   oversteps;
5. sign: band voxels from their nearest triangle's side label, deeper voxels by region majority;
6. the tracer's int16 copy (``SDFGrid.trace``) signed by the nearest face's side, with "thin" flags.

The result is cached on disk as .npz keyed by a hash of the mesh arrays, h, the band and ``CODE_VERSION``.
"""

from __future__ import annotations

import functools
import hashlib
import logging
import os
import time
from pathlib import Path

import igl
import jax
import jax.numpy as jnp
import numpy as np
import scipy.ndimage as ndi
from jaxtyping import Array, Float

from .._core import ConfigError, ResourceError, Scene, write_atomic
from ._sdf import SDFGrid, encode_trace
from ._sdf_raster import _band_volume, decode_keys, rasterize_band
from ._sdf_sign import fill_deep_sign, side_labels, weld_components

log = logging.getLogger(__name__)

# Bump when the algorithm changes what a build produces (invalidates caches).
CODE_VERSION = "sdf-1"
# Refuse builds whose estimated peak host memory exceeds this.
MAX_BUILD_BYTES = 2 * 1024**3
# Peak host bytes per voxel during a build (two key arrays, decoded distances, bounds, labels, values,
# tracer codes): measured 26 B/voxel on Sponza (peak RSS growth / voxels), rounded up.
_BYTES_PER_VOXEL = 32
# Exact band half-width in voxels: > √3 so all 8 corners of every cell the surface crosses are exact.
# The default is the widest of these whose rasterization stays within _PAIR_BUDGET point-triangle pairs
# (a wider band gives exact distances further out: longer sphere-tracing steps, less pessimistic soft
# visibility near surfaces). Sponza at h = 0.127 gets 2; the Cornell box 6.
BAND_CHOICES = (6.0, 4.0, 3.0, 2.0)
_PAIR_BUDGET = 64_000_000
# Front- and back-facing nearest faces closer than this (voxels) make a "thin" surface (see SDFGrid.trace).
THIN_VOXELS = 1.5
# Distances closer than this (voxels) are a tie for the inside test (float32 noise is ~10⁻⁵ voxel).
_TIE_VOXELS = 1e-3
# Default resolution (quality = 1): at least this many voxels along the longest axis ...
_MIN_CELLS_LONG_AXIS = 128
# ... at most this many voxels in total (scaled by quality³) ...
_MAX_VOXELS = 1 << 24
# ... and two voxels across the thinnest tenth (by area) of the solids.
_VOXELS_ACROSS_FEATURE = 2.0
# Coarse lattice for the far-field bound: at most this many exact distance queries.
_MAX_COARSE_POINTS = 40_000


def _mesh_arrays(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(scene.vertices, np.float64), np.asarray(scene.faces, np.int64)


def _solid_feature_size(v, f, comp, n_comp, back, front) -> float | None:
    """Area-weighted 10th percentile of solid components' thickness 4·volume/area (None without solids).

    4V/A is the diameter of a long cylinder and twice the thickness of a slab: a cheap, rotation-invariant
    "how thin are the solids" scale. Sheets have no thickness and are represented unsigned at any h.
    """
    solid = back | front
    if not solid.any():
        return None
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    vol6 = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))  # divergence theorem
    c_area = np.bincount(comp, weights=area, minlength=n_comp)[solid]
    c_vol = np.abs(np.bincount(comp, weights=vol6, minlength=n_comp)[solid]) / 6.0
    thick = 4.0 * c_vol / np.maximum(c_area, 1e-300)
    order = np.argsort(thick)
    cum = np.cumsum(c_area[order])
    return float(thick[order][np.searchsorted(cum, 0.1 * cum[-1])])


def _labels(v: np.ndarray, f: np.ndarray):
    comp, n_comp = weld_components(v, f)
    back, front = side_labels(v, f, comp, n_comp)
    return comp, n_comp, back, front


def _voxel_size(v: np.ndarray, f: np.ndarray, labels, quality: float) -> float:
    if not (np.isfinite(quality) and quality > 0):
        raise ConfigError(f"quality must be a positive finite number, got {quality}")
    ext = np.maximum(v.max(0) - v.min(0), 1e-9 * max(float(np.max(v.max(0) - v.min(0))), 1e-30))
    h_extent = float(ext.max()) / _MIN_CELLS_LONG_AXIS
    feature = _solid_feature_size(v, f, *labels)
    h_feature = h_extent if feature is None else feature / _VOXELS_ACROSS_FEATURE
    h_budget = float(np.prod(ext) / _MAX_VOXELS) ** (1.0 / 3.0)
    h = max(h_budget / quality, min(h_extent, h_feature) / quality)
    return float(f"{h:.3g}")


def default_voxel_size(scene: Scene, *, quality: float = 1.0) -> float:
    """Voxel size derived from the scene: fine enough for its extent and its thinnest solids, within budget.

    h = max(h_budget, min(h_extent, h_feature)), each term divided by ``quality``:

    * h_extent = longest bbox side / 128: never coarser than 128 voxels along the longest axis;
    * h_feature = t₁₀ / 2: two voxels across t₁₀, the area-weighted 10th percentile of the solids'
      thickness 4·volume/area (so thin columns and arches keep a negative core);
    * h_budget = (bbox volume / 2²⁴)^(1/3) (quality³ times more voxels allowed): the memory and
      speed cap (16.8M voxels: 64 MB of float32 values plus 32 MB of int16 tracer codes).

    Cornell box (mm): 4.37 (the extent term). Crytek Sponza: 0.127 (the budget term; t₁₀ = 0.19 m, so
    the arches, ~0.46 m thick, get ~3.6 voxels and the 1.05 m ground-floor columns ~8).
    The result is rounded to 3 significant digits so it is stable under tiny mesh edits.

    Raises:
        ConfigError: quality not positive and finite.
    """
    v, f = _mesh_arrays(scene)
    return _voxel_size(v, f, _labels(v, f), quality)


def _default_band(v: np.ndarray, f: np.ndarray, h: float) -> float:
    """Widest band of BAND_CHOICES whose rasterization visits at most _PAIR_BUDGET lattice points
    (estimated per triangle as the smaller of its grown box and 4x its offset-solid volume)."""
    tri = (v[f] - v.min(0)) / h
    ext = tri.max(axis=1) - tri.min(axis=1)
    for band in BAND_CHOICES:
        box = np.prod(np.floor(ext + 2 * band) + 1, axis=1)
        pairs = np.minimum(box, np.maximum(4 * _band_volume(tri, band), (2 * band + 2) ** 3)).sum()
        if pairs <= _PAIR_BUDGET:
            return band
    return BAND_CHOICES[-1]


def grid_layout(
    lo: np.ndarray, hi: np.ndarray, h: float, band: float
) -> tuple[np.ndarray, tuple[int, int, int]]:
    """Origin and lattice shape covering the box [lo, hi] plus ceil(band) + 1 voxels of margin."""
    pad = int(np.ceil(band)) + 1
    origin = lo - pad * h
    shape = np.ceil((hi + pad * h - origin) / h).astype(np.int64) + 1
    return origin, (int(shape[0]), int(shape[1]), int(shape[2]))


def estimate_build_bytes(shape: tuple[int, int, int]) -> int:
    return int(np.prod(shape)) * _BYTES_PER_VOXEL


def _coarse_lower_bound(
    v: np.ndarray, f: np.ndarray, origin: np.ndarray, h: float, shape: tuple[int, int, int]
) -> np.ndarray:
    """Lower bound of the distance (voxels) at each lattice point from exact distances on a coarse lattice."""
    n = np.asarray(shape)
    k = int(np.ceil((np.prod(n) / _MAX_COARSE_POINTS) ** (1.0 / 3.0)))
    k = max(k, 2)
    nc = -(-n // k) + 1  # coarse points at fine indices 0, k, ..., so the cells cover indices 0 .. n - 1
    axes = [np.arange(c) * k for c in nc]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    d2, _, _ = igl.point_mesh_squared_distance(origin + h * pts.astype(np.float64), v, f)
    dc = jnp.asarray((np.sqrt(d2) / h).reshape(tuple(nc)).astype(np.float32))
    return np.asarray(_max_plus(dc, k, shape))


@functools.partial(jax.jit, static_argnums=(1, 2))
def _max_plus(dc: Float[Array, "cx cy cz"], k: int, shape: tuple[int, int, int]) -> Float[Array, "nx ny nz"]:
    # For fine point p in coarse cell C: max over C's corners c of D_c − |p − c| (1-Lipschitz), with the
    # |p − c| table shared by all cells; one fused pass under jit.
    nc = dc.shape
    off = jnp.arange(k, dtype=dc.dtype)
    lb = None
    for a, b, c in ((a, b, c) for a in (0, 1) for b in (0, 1) for c in (0, 1)):
        corner = dc[a : a + nc[0] - 1, b : b + nc[1] - 1, c : c + nc[2] - 1]
        dist = jnp.sqrt(
            (off[:, None, None] - a * k) ** 2
            + (off[None, :, None] - b * k) ** 2
            + (off[None, None, :] - c * k) ** 2
        )
        term = corner[:, None, :, None, :, None] - dist[None, :, None, :, None, :]
        lb = term if lb is None else jnp.maximum(lb, term)
    lb = lb.reshape((nc[0] - 1) * k, (nc[1] - 1) * k, (nc[2] - 1) * k)
    return lb[: shape[0], : shape[1], : shape[2]]


def mesh_hash(v: np.ndarray, f: np.ndarray, h: float, band: float) -> str:
    m = hashlib.sha256()
    m.update(np.ascontiguousarray(v, np.float32).tobytes())
    m.update(np.ascontiguousarray(f, np.int32).tobytes())
    m.update(f"{h!r}|{band!r}|{CODE_VERSION}".encode())
    return m.hexdigest()


def _cache_path(cache_dir, digest: str) -> Path | None:
    if cache_dir is False:
        return None
    if cache_dir is None:
        root = os.environ.get("PROBEPLACE_CACHE_DIR")
        base = Path(root) / "sdf" if root else Path.home() / ".cache" / "probeplace" / "sdf"
    else:
        base = Path(cache_dir)
    return base / f"sdf-{digest[:32]}.npz"


def _grid_from_arrays(values, trace, origin, h, band, digest) -> SDFGrid:
    return SDFGrid(
        values=jnp.asarray(values, jnp.float32),
        trace=jnp.asarray(trace, jnp.int16),
        origin=jnp.asarray(origin, jnp.float32),
        voxel_size=jnp.asarray(h, jnp.float32),
        band=float(band),
        mesh_hash=digest,
    )


def build_sdf(
    scene: Scene,
    *,
    voxel_size: float | None = None,
    cache_dir: str | os.PathLike | bool | None = None,
    progress: bool = False,
    band: float | None = None,
) -> SDFGrid:
    """Signed-distance grid of a scene's triangles (host build; the result is a JAX pytree).

    Sign: negative inside solids by the per-component winding-number rule of :mod:`._sdf_sign` (single-
    sided sheets are unsigned, i.e. positive on both sides). Magnitude: exact within ``band`` voxels of the
    surface, a lower bound beyond. Not differentiable (a numpy/libigl build).

    Args:
        scene: the scene; its triangles are used, materials ignored.
        voxel_size: lattice spacing in scene units; ``None`` picks :func:`default_voxel_size`.
        cache_dir: directory of the .npz cache; ``None`` uses ``$PROBEPLACE_CACHE_DIR/sdf`` or
            ``~/.cache/probeplace/sdf``; ``False`` disables caching.
        progress: log each stage's time at INFO level.
        band: exact band half-width in voxels (≥ √3 keeps every surface-crossing cell exact); ``None``
            picks the widest of ``BAND_CHOICES`` whose build stays within a fixed work budget.

    Returns:
        The grid; float32 leaves.

    Raises:
        ConfigError: non-positive voxel size or band.
        ResourceError: the lattice would need more than 2 GiB to build (the message gives the estimate).
    """
    v, f = _mesh_arrays(scene)
    clock = _Clock(progress, scene.name)
    labels = _labels(v, f)
    comp, n_comp, back, front = labels
    clock("side labels (%d components, %d solid)", n_comp, int((back | front).sum()))
    h = _voxel_size(v, f, labels, 1.0) if voxel_size is None else float(voxel_size)
    if not (np.isfinite(h) and h > 0):
        raise ConfigError(f"voxel_size must be a positive finite number, got {voxel_size}")
    band = _default_band(v, f, h) if band is None else float(band)
    if not (np.isfinite(band) and band >= 1.0):
        raise ConfigError(f"band must be ≥ 1 voxel, got {band}")
    origin, shape = grid_layout(v.min(0), v.max(0), h, band)
    need = estimate_build_bytes(shape)
    if need > MAX_BUILD_BYTES:
        raise ResourceError(
            f"SDF of {scene.name!r} at voxel_size={h:g} is a {shape[0]}×{shape[1]}×{shape[2]} lattice "
            f"({np.prod(shape) / 1e6:.0f}M voxels, ~{need / 2**30:.1f} GiB to build, limit "
            f"{MAX_BUILD_BYTES / 2**30:.0f} GiB); use a larger voxel_size"
        )
    digest = mesh_hash(v, f, h, band)
    path = _cache_path(cache_dir, digest)
    if path is not None and path.exists():
        try:
            with np.load(path) as z:
                return _grid_from_arrays(
                    z["values"], z["trace"], z["origin"], float(z["voxel_size"]), band, digest
                )
        except (OSError, KeyError, ValueError) as err:  # a corrupt file is rebuilt, not fatal
            log.warning("ignoring unreadable SDF cache %s: %s", path, err)

    tri_vox = (v[f] - origin) / h
    key_front, key_back, stats = rasterize_band(tri_vox, shape, band, ~back[comp], ~front[comp])
    clock("exact band (%d pairs, %d chunks)", stats["pairs"], stats["chunks"])
    _, d_front, in_front, _ = decode_keys(key_front, band)
    _, d_back, in_back, _ = decode_keys(key_back, band)
    # Where a face seen from the front and one seen from behind are (almost) equally near, the lattice
    # cannot sign the surface (a plate thinner than ~a voxel, two opposite layers): flag it for the tracer.
    big = np.float32(4 * band)  # stands in for "none within the band" (decode gives inf)
    thin = np.abs(np.minimum(d_front, big) - np.minimum(d_back, big)) <= THIN_VOXELS
    thin = (thin & (np.maximum(d_front, d_back) < big)).reshape(shape)
    in_band, dist, inside, behind = decode_keys(np.minimum(key_front, key_back), band)
    # Union of solids at ties: a face seen from the front and one seen from behind at the same distance
    # (a block standing on a floor: its bottom face and the floor) make the voxel inside if either says so;
    # the scatter-min alone would let float32 noise in the distances decide.
    tie = np.abs(np.minimum(d_front, big) - np.minimum(d_back, big)) <= _TIE_VOXELS
    inside |= tie & (in_front | in_back)
    del key_front, key_back, d_front, d_back, in_front, in_back, tie
    in_band, dist = in_band.reshape(shape), dist.reshape(shape)
    lb = _coarse_lower_bound(v, f, origin, h, shape)
    # Second bound from the band itself: a surface point is within h√3/2 of a lattice point whose distance
    # is ≤ h√3/2 ≤ band·h, i.e. of a band voxel, so d(p) ≥ e(p) − h√3/2 + ... ≥ e(p) + band − √3 voxels
    # with e(p) the distance to the nearest band voxel, itself ≥ its chessboard distance (cheap transform).
    e = ndi.distance_transform_cdt(~in_band, metric="chessboard").astype(np.float32)
    lb = np.maximum(lb, e + np.float32(band - np.sqrt(3.0)))
    mag = np.where(in_band, dist, np.maximum(np.float32(band), lb))
    del lb, e
    clock("far-field bound")
    # Signs of the band's outer rim come from the deep fill, not from the nearest face: at the band edge a
    # face may fall just outside the band by float rounding while a coincident opposite face (a block's
    # bottom on a floor) falls inside, so the tie rule above cannot see both and the rim takes the wrong
    # side (a one-voxel layer of wrong sign inside the Cornell blocks, tests/geometry/test_sdf_build.py).
    sign_band = in_band & (dist <= np.float32(band - 1.0))
    inside = fill_deep_sign(sign_band, inside.reshape(shape))
    clock("sign fill")
    hf = np.float32(h)
    values = np.where(inside, -mag, mag) * hf
    oriented = np.where(behind.reshape(shape), -dist, np.where(in_band, dist, values / hf))
    trace = encode_trace(oriented, thin)
    del mag, inside, dist, behind, in_band, oriented, thin
    if path is not None:
        arrays = {"values": values, "trace": trace, "origin": origin}
        arrays |= {"voxel_size": np.float64(h), "band": np.float64(band)}
        write_atomic(path, lambda f: np.savez(f, **arrays))  # readers see the old file or the whole new one
        clock("cache write %s", path)
    return _grid_from_arrays(values, trace, origin, h, band, digest)


class _Clock:
    def __init__(self, enabled: bool, name: str):
        self.enabled, self.name, self.t = enabled, name, time.perf_counter()

    def __call__(self, msg: str, *args) -> None:
        now = time.perf_counter()
        if self.enabled:
            log.info("build_sdf(%s): " + msg + " %.2f s", self.name, *args, now - self.t)
        self.t = now
