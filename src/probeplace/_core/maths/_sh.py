"""Spherical harmonics L2 basis (9 coefficients per colour) in the three.js convention, in NumPy.

Convention (the one three.js ``SphericalHarmonics3`` / ``LightProbe`` and Three.V8 use, so a
coefficient array can be handed to them as is):

* real SH basis with the usual normalisation (Ramamoorthi & Hanrahan 2001, "An Efficient
  Representation for Irradiance Environment Maps", Eq. 3), evaluated on the world-frame unit
  vector (x, y, z) (right-handed, +Y up), in the order
  ``Y00, Y1-1 (y), Y10 (z), Y11 (x), Y2-2 (xy), Y2-1 (yz), Y20 (3z²-1), Y21 (xz), Y22 (x²-y²)``;
* the coefficients c_lm are those of the incident **radiance** L(ω) = Σ c_lm Y_lm(ω);
* irradiance at a receiver normal n is E(n) = Σ Â_l c_lm Y_lm(n) with Â₀ = π, Â₁ = 2π/3, Â₂ = π/4
  (R&H 2001 Eq. 8-9), which is exactly three.js' ``shGetIrradianceAt`` (0.886227 = π·0.282095, …).
"""

from __future__ import annotations

from types import ModuleType

import numpy as np

SH_ORDER = ("Y00", "Y1-1", "Y10", "Y11", "Y2-2", "Y2-1", "Y20", "Y21", "Y22")
SH_CONVENTION = (
    "three.js SphericalHarmonics3: real SH L2 coefficients of incident radiance in the world frame "
    "(right-handed, +Y up), order Y00, Y1-1(y), Y10(z), Y11(x), Y2-2(xy), Y2-1(yz), Y20(3z^2-1), "
    "Y21(xz), Y22(x^2-y^2); irradiance E(n) = sum_lm A_l c_lm Y_lm(n), A = (pi, 2pi/3, pi/4) "
    "(three.js shGetIrradianceAt)"
)
# Â_l per coefficient (R&H 2001 Eq. 8-9).
COSINE_LOBE = np.array([np.pi] + [2.0 * np.pi / 3.0] * 3 + [np.pi / 4.0] * 5)


def sh_basis(directions, xp: ModuleType = np):
    """(..., 3) unit directions → (..., 9) real SH basis values (R&H 2001 Eq. 3 constants).

    ``xp`` is the array module (``numpy`` or ``jax.numpy``), so the export (NumPy only) and the
    JAX shading use one definition.
    """
    x, y, z = directions[..., 0], directions[..., 1], directions[..., 2]
    return xp.stack(
        [
            xp.full_like(x, 0.282095),
            0.488603 * y,
            0.488603 * z,
            0.488603 * x,
            1.092548 * x * y,
            1.092548 * y * z,
            0.315392 * (3.0 * z * z - 1.0),
            1.092548 * x * z,
            0.546274 * (x * x - y * y),
        ],
        axis=-1,
    )
