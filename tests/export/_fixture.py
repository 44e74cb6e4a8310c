"""The asymmetric probe set every export test uses (NumPy only; golden files are made from it).

Asymmetric on purpose: the probes differ along +X, +Y and +Z by different amounts, so a mirrored,
rotated or axis-swapped export cannot pass for the right one. Row 4 is inactive (capacity padding),
``units_m`` is not 1, and the SH and maps are fixed closed-form values (no BLAS in the golden path).
"""

from __future__ import annotations

import os

import numpy as np

from probeplace.export import ExportProbes, LightFieldMaps
from probeplace.export._octa import add_border, texel_directions

POSITIONS = np.array(
    [
        [0.5, 0.25, 0.125],
        [2.0, 0.25, 0.125],  # +X of probe 0
        [0.5, 1.5, 0.125],  # +Y of probe 0
        [0.5, 0.25, 3.0],  # +Z of probe 0
        [9.0, 9.0, 9.0],  # inactive
        [-1.3, 0.7, -0.45],  # not exactly representable in float32
    ],
    np.float32,
)
ACTIVE = np.array([True, True, True, True, False, True])
INSIDE = np.array([False, False, False, False, False, True])
UNITS_M = 0.5
RES, IRR_RES, MOM_RES = 8, 4, 4
FAR = 20.0


def linear_radiance_params(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per probe a (3,) constant and a (3, 3) gradient: L(ω) = a + B ω (RGB rows of B)."""
    k = np.arange(n, dtype=np.float64)[:, None]
    a = 1.0 + 0.25 * k + np.array([0.0, 0.1, 0.2])
    b = 0.3 * np.stack([np.sin(k + c + np.arange(3)) for c in range(3)], axis=1)  # (n, 3 rgb, 3 xyz)
    return a, b


def fixture_sh(n: int) -> np.ndarray:
    """SH of L = a + Bω in the three.js convention, in closed form (∫ Y00 = 0.282095·4π,
    ∫ ω_k Y1m = 0.488603·4π/3 for the matching axis; band 2 vanishes)."""
    a, b = linear_radiance_params(n)
    sh = np.zeros((n, 9, 3))
    sh[:, 0] = a * (4 * np.pi * 0.282095)  # ∫ a Y00 = a · 0.282095 · 4π
    c1 = 4 * np.pi / 3 * 0.488603  # ∫ (b·ω) · 0.488603 ω_k = b_k · 0.488603 · 4π/3
    sh[:, 1] = b[:, :, 1] * c1  # Y1-1 ∝ y
    sh[:, 2] = b[:, :, 2] * c1  # Y10 ∝ z
    sh[:, 3] = b[:, :, 0] * c1  # Y11 ∝ x
    return sh.astype(np.float32)


def fixture_maps(n: int, res: int = RES) -> LightFieldMaps:
    a, b = linear_radiance_params(n)
    d = texel_directions(res)  # (res, res, 3)
    rad = a[:, None, None, :] + (b[:, None, None] * d[None, :, :, None, :]).sum(-1)
    emission = np.zeros_like(rad)
    emission[..., 1] = 0.5 * np.maximum(d[..., 1], 0.0)  # a "sky" from above
    dm = texel_directions(MOM_RES)
    mean = 1.0 + 0.5 * np.arange(n)[:, None, None] + 0.25 * dm[None, ..., 0]
    moments = np.stack([mean, mean * mean + 0.01], axis=-1)
    # E(n) of L = a + Bω: π a + (2π/3) B n (Ramamoorthi & Hanrahan 2001, Eq. 8-9: Â₀ = π, Â₁ = 2π/3)
    dn = texel_directions(IRR_RES)
    irr = np.pi * a[:, None, None, :] + 2 * np.pi / 3 * (b[:, None, None] * dn[None, :, :, None, :]).sum(-1)
    return LightFieldMaps(
        irradiance=add_border(irr).astype(np.float32),
        moments=add_border(moments).astype(np.float32),
        radiance=add_border(rad).astype(np.float32),
        emission=add_border(emission).astype(np.float32),
        far=FAR,
    )


def asymmetric_probes(*, with_sh: bool = True, with_maps: bool = False) -> ExportProbes:
    n = len(POSITIONS)
    return ExportProbes(
        positions=POSITIONS,
        active=ACTIVE,
        method="test-asymmetric",
        units_m=UNITS_M,
        metadata={"seed": 7, "note": "asymmetric export fixture"},
        sh=fixture_sh(n) if with_sh else None,
        inside=INSIDE,
        maps=fixture_maps(n) if with_maps else None,
    )


def write_baked_npz(path: str | os.PathLike) -> None:
    """Baked probes in the ``probes.save_probes`` layout (keys and format tag), written with NumPy alone."""
    maps = fixture_maps(len(POSITIONS))
    dist = np.ones(maps.radiance.shape[:-1], np.float32)
    np.savez_compressed(
        path, format=np.asarray("probeplace.LightFieldProbes/1"), pos_world=POSITIONS, active=ACTIVE,
        inside=INSIDE, radiance=maps.radiance, emission=maps.emission, normal=maps.radiance, distance=dist,
        irradiance=maps.irradiance, moments=maps.moments, far=np.asarray(maps.far, np.float32),
    )  # fmt: skip
