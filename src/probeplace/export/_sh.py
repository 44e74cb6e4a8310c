"""Spherical harmonics L2 projection of baked octahedral radiance maps, in NumPy. The basis and its
convention (three.js ``SphericalHarmonics3``; Ramamoorthi & Hanrahan 2001) are in ``_core/maths/_sh.py``.
"""

from __future__ import annotations

import numpy as np

from .._core.maths._sh import COSINE_LOBE as COSINE_LOBE
from .._core.maths._sh import SH_CONVENTION as SH_CONVENTION
from .._core.maths._sh import SH_ORDER as SH_ORDER
from .._core.maths._sh import sh_basis as sh_basis
from ._octa import texel_directions, texel_solid_angles


def project_radiance(bordered_radiance: np.ndarray) -> np.ndarray:
    """Project bordered octahedral radiance maps onto SH L2: c_lm = Σ_texels L(ω) Y_lm(ω) Δω.

    Args:
        bordered_radiance: (P, R+2, R+2, 3) maps with the one-texel border (the LightFieldProbes layout).

    Returns:
        (P, 9, 3) float32 radiance coefficients (three.js convention, module docstring).
    """
    res = bordered_radiance.shape[-2] - 2
    interior = np.asarray(bordered_radiance, np.float64)[:, 1:-1, 1:-1, :].reshape(-1, res * res, 3)
    y = sh_basis(texel_directions(res).reshape(-1, 3))  # (K, 9)
    w = texel_solid_angles(res).reshape(-1)
    return np.einsum("k,kj,pkc->pjc", w, y, interior).astype(np.float32)


def sh_irradiance(coeffs: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Irradiance E(n) from (P, 9, 3) radiance coefficients at (K, 3) unit normals → (P, K, 3)."""
    y = sh_basis(np.asarray(normals, np.float64)) * COSINE_LOBE  # (K, 9)
    return np.einsum("kj,pjc->pkc", y, np.asarray(coeffs, np.float64))


def sh_radiance(coeffs: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Radiance L(ω) from (P, 9, 3) coefficients at (K, 3) unit directions → (P, K, 3)."""
    y = sh_basis(np.asarray(directions, np.float64))
    return np.einsum("kj,pjc->pkc", y, np.asarray(coeffs, np.float64))
