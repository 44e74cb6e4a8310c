"""Area-stratified surface samples: the "texels" of the global visibility atlas (DESIGN.md).

Wang et al. 2019 map visibility into a UV texture atlas; scenes here have no UVs, so the atlas is a set
of points on the surface, each standing for a patch of area (its weight), with the normal and material
of its triangle. Coverage of a sample by a probe then stands for coverage of that patch.

Stratification (so integrals over the surface have low variance and every part is represented):

* across triangles: systematic sampling of the cumulative area, n_t = ⌊C_t/s² + u⌋ − ⌊C_{t-1}/s² + u⌋
  for one uniform offset u (Madow 1949), so |n_t − A_t/s²| < 1, then at least one sample per triangle;
* within a triangle: n_t strata along the first of two uniform coordinates, mapped to the triangle by
  the area-preserving warp (1 − √r₁, √r₁(1 − r₂), √r₁ r₂) (Osada et al. 2002, "Shape distributions", §4.2);
* weights A_t / n_t, so the weights of a triangle add up to its area and all weights to the mesh area.

With ``min_one=False`` (a requested sample count, e.g. a refiner's few-thousand-sample problem) the "at least
one per triangle" floor is dropped, so a mesh with more triangles than samples (Crytek Sponza: 262k) still
gets about the requested count: a triangle smaller than s² then holds one sample with probability A_t/s²,
and the samples on such triangles share their total area equally (each stands for about s²), so the
weights still add up to the mesh area; larger triangles keep A_t / n_t.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from .._core import ConfigError, Scene

# Default density: at most this many samples at quality 1 (scaled by quality²) ...
_MAX_SAMPLES = 1 << 18
# ... and no finer than this many voxels of the default SDF between samples.
_VOXELS_PER_SAMPLE = 2.0


class SurfaceSamples(eqx.Module):
    """Points on the scene's surface with the patch each stands for.

    Attributes:
        position: sample position, world frame, on its triangle.
        normal: unit geometric (face) normal of the triangle, front side (counter-clockwise).
        area: area the sample stands for, scene units²; sums to the mesh area.
        material: material row of the triangle.
        tri: triangle index.
    """

    position: Float[Array, "n 3"]
    normal: Float[Array, "n 3"]
    area: Float[Array, " n"]
    material: Int[Array, " n"]
    tri: Int[Array, " n"]

    def __check_init__(self):
        n = self.position.shape[0]
        for name in ("normal", "area", "material", "tri"):
            if getattr(self, name).shape[0] != n:
                raise ValueError(f"{name} must have {n} rows like position, got {getattr(self, name).shape}")

    @property
    def n(self) -> int:
        return int(self.position.shape[0])


def _tri_areas(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    v = np.asarray(scene.vertices, np.float64)
    tri = v[np.asarray(scene.faces)]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(cross, axis=1)
    return tri, 0.5 * norm, cross / np.maximum(norm, 1e-300)[:, None]


def default_sample_spacing(scene: Scene, *, quality: float = 1.0) -> float:
    """Sample spacing s (one sample per s² of area), derived from the scene.

    s = max(2·h / quality, √(A / (2¹⁸·quality²))): two SDF voxels (h from :func:`default_voxel_size`,
    the extent and thinnest solids) between samples, but no more than 2¹⁸·quality² samples over the
    mesh area A. Cornell box: 8.74 mm (~25k samples); Crytek Sponza: 0.301 (the budget, 262k samples).
    Rounded to 3 significant digits.

    Raises:
        ConfigError: quality not positive and finite.
    """
    from ._sdf_build import default_voxel_size

    if not (np.isfinite(quality) and quality > 0):
        raise ConfigError(f"quality must be a positive finite number, got {quality}")
    _, area, _ = _tri_areas(scene)
    h = default_voxel_size(scene, quality=quality)
    s = max(_VOXELS_PER_SAMPLE * h, float(np.sqrt(area.sum() / (_MAX_SAMPLES * quality**2))))
    return float(f"{s:.3g}")


def sample_counts(area: np.ndarray, spacing: float, offset: float, *, min_one: bool = True) -> np.ndarray:
    """Samples per triangle by systematic sampling of the cumulative area; ≥ 1 each unless ``min_one`` is
    False (see module docstring)."""
    c = np.concatenate([[0.0], np.cumsum(area / spacing**2)])
    n = np.diff(np.floor(c + offset)).astype(np.int64)
    return np.maximum(n, 1) if min_one else n


def sample_surface(
    scene: Scene, *, key: jax.Array, spacing: float | None = None, min_one: bool = True
) -> SurfaceSamples:
    """Area-stratified samples of the scene's triangles (host computation; deterministic per key).

    Args:
        scene: the scene.
        key: PRNG key; the same key gives the same samples.
        spacing: one sample per spacing² of area (scene units); ``None`` uses :func:`default_sample_spacing`.
        min_one: at least one sample per triangle (the coverage atlas); ``False`` keeps the count near
            A/spacing² on meshes with more triangles than that (module docstring).

    Returns:
        The samples, float32 / int32, ordered by triangle.

    Raises:
        ConfigError: spacing not positive and finite.
    """
    s = default_sample_spacing(scene) if spacing is None else float(spacing)
    if not (np.isfinite(s) and s > 0):
        raise ConfigError(f"spacing must be a positive finite number, got {spacing}")
    tri, area, normal = _tri_areas(scene)
    k_off, k_pts = jax.random.split(key)
    offset = float(jax.random.uniform(k_off, ()))
    counts = sample_counts(area, s, offset, min_one=min_one)
    n = int(counts.sum())
    if n == 0:  # a tiny mesh at a coarse spacing: one sample on the largest triangle
        counts[int(np.argmax(area))] = n = 1
    t = np.repeat(np.arange(len(area)), counts)
    first = np.cumsum(counts) - counts
    rank = np.arange(n) - first[t]  # stratum index within the triangle
    xi = np.asarray(jax.random.uniform(k_pts, (n, 2), jnp.float32), np.float64)
    r1 = (rank + xi[:, 0]) / counts[t]  # stratified along r1 (area-proportional: the warp is area-preserving)
    r2 = xi[:, 1]
    sq = np.sqrt(r1)
    bary = np.stack([1.0 - sq, sq * (1.0 - r2), sq * r2], axis=1)
    pos = np.einsum("nk,nkj->nj", bary, tri[t])
    weights = area[t] / counts[t]
    if not min_one:
        # triangles under one stratum hold a sample with probability A_t/s²: they share their area
        small = area[t] < s * s
        if small.any():
            weights[small] = area[area < s * s].sum() / small.sum()
    return SurfaceSamples(
        position=jnp.asarray(pos.astype(np.float32)),
        normal=jnp.asarray(normal[t].astype(np.float32)),
        area=jnp.asarray(weights.astype(np.float32)),
        material=jnp.asarray(np.asarray(scene.tri_material)[t].astype(np.int32)),
        tri=jnp.asarray(t.astype(np.int32)),
    )
