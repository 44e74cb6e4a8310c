"""NumPy twins of the octahedral helpers in ``probeplace._core.maths._octahedral`` (which use JAX).

Exporters import no JAX, so the few pieces they need are re-stated here with the *same* conventions
(Cigolle et al. 2014, JCGT 3(2) §3.6; octahedron axis world +Z; column ↔ u, row ↔ v, row 0 at v = −1;
stored maps carry the one-texel DDGI border, Luo 2022 §4.3.5). ``tests/export/test_sh_numpy.py`` holds
them equal to the JAX originals.
"""

from __future__ import annotations

import numpy as np


def _sign_not_zero(x: np.ndarray) -> np.ndarray:
    return np.where(x >= 0, 1.0, -1.0).astype(x.dtype)


def octahedron_point(uv: np.ndarray) -> np.ndarray:
    """The point of |x| + |y| + |z| = 1 that ``uv`` ∈ [−1, 1]² stands for (not normalised)."""
    u, v = uv[..., 0], uv[..., 1]
    z = 1.0 - np.abs(u) - np.abs(v)
    lower = z < 0
    x = np.where(lower, (1.0 - np.abs(v)) * _sign_not_zero(u), u)
    y = np.where(lower, (1.0 - np.abs(u)) * _sign_not_zero(v), v)
    return np.stack([x, y, z], axis=-1)


def oct_decode(uv: np.ndarray) -> np.ndarray:
    """Octahedral ``uv`` → unit direction (Cigolle 2014, Listing 6 ``oct_to_float32x3``)."""
    p = octahedron_point(uv)
    return p / np.linalg.norm(p, axis=-1, keepdims=True)


def oct_encode(direction: np.ndarray) -> np.ndarray:
    """Direction(s) (non-zero) → ``uv`` ∈ [−1, 1]² (Cigolle 2014, Listing 6 ``float32x3_to_oct``)."""
    p = direction[..., :2] / np.sum(np.abs(direction), axis=-1, keepdims=True)
    folded = (1.0 - np.abs(p[..., ::-1])) * _sign_not_zero(p)
    return np.where(direction[..., 2:3] < 0, folded, p)


def texel_uv(res: int) -> np.ndarray:
    """(res, res, 2) texel centres in ``uv`` (float64)."""
    c = (np.arange(res, dtype=np.float64) + 0.5) * (2.0 / res) - 1.0
    vv, uu = np.meshgrid(c, c, indexing="ij")
    return np.stack([uu, vv], axis=-1)


def texel_directions(res: int) -> np.ndarray:
    """(res, res, 3) unit directions through the interior texel centres (float64)."""
    return oct_decode(texel_uv(res))


def texel_solid_angles(res: int, sub: int = 4) -> np.ndarray:
    """(res, res) solid angle of each interior texel (dω = du dv / ‖p‖³, midpoint rule), sums to 4π."""
    p = octahedron_point(texel_uv(res * sub))
    w = (2.0 / (res * sub)) ** 2 / np.sum(p * p, axis=-1) ** 1.5
    return w.reshape(res, sub, res, sub).sum(axis=(1, 3))


def border_index(res: int) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) of the interior texel each texel of the bordered (res+2)² map holds."""
    c = (np.arange(res + 2, dtype=np.float64) - 0.5) * (2.0 / res) - 1.0
    vv, uu = np.meshgrid(c, c, indexing="ij")
    u, v = uu, vv
    out_u = np.abs(u) > 1
    u, v = np.where(out_u, 2.0 * np.sign(u) - u, u), np.where(out_u, -v, v)
    out_v = np.abs(v) > 1
    u, v = np.where(out_v, -u, u), np.where(out_v, 2.0 * np.sign(v) - v, v)
    to_idx = lambda x: np.clip(np.floor((x + 1.0) * (res / 2.0)), 0, res - 1).astype(np.int64)
    return to_idx(v), to_idx(u)


def add_border(interior: np.ndarray) -> np.ndarray:
    """(..., R, R, C) interior maps → (..., R+2, R+2, C) with the octahedral border ring."""
    rows, cols = border_index(interior.shape[-2])
    return interior[..., rows, cols, :]


def sample_bilinear(bordered: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Bilinear lookups of bordered maps.

    Args:
        bordered: (P, R+2, R+2, C) maps.
        directions: (K, 3) directions, shared by all P maps.

    Returns:
        (P, K, C) filtered values (the same arithmetic as ``_core.sample_bilinear``).
    """
    res = bordered.shape[-2] - 2
    s = (oct_encode(directions) + 1.0) * (res / 2.0) + 0.5
    s = np.clip(s, 0.5, res + 0.5)
    i0 = np.minimum(np.floor(s).astype(np.int64), res)
    f = s - i0
    col0, row0 = i0[:, 0], i0[:, 1]
    fu, fv = f[:, 0, None], f[:, 1, None]
    a = bordered[:, row0, col0]
    b = bordered[:, row0, col0 + 1]
    c = bordered[:, row0 + 1, col0]
    d = bordered[:, row0 + 1, col0 + 1]
    return (a * (1 - fu) + b * fu) * (1 - fv) + (c * (1 - fu) + d * fu) * fv


def resample_bordered(bordered: np.ndarray, res: int) -> np.ndarray:
    """Bilinearly resample (P, R+2, R+2, C) bordered maps to interior ``res`` and re-add the border.

    Returns the input unchanged (a copy) when the resolution already matches.
    """
    if bordered.shape[-2] - 2 == res:
        return bordered.copy()
    dirs = texel_directions(res).reshape(-1, 3)
    vals = sample_bilinear(bordered.astype(np.float64), dirs)
    interior = vals.reshape(bordered.shape[0], res, res, bordered.shape[-1])
    return add_border(interior).astype(bordered.dtype)
