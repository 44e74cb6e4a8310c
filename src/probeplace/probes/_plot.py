"""A contact sheet of baked probe maps: one row per probe, one column per map, as a PNG."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .._core import LightFieldProbes, load_pyplot

_COLUMNS = ("radiance", "emission", "normal", "distance", "irradiance", "moments σ")


def _tonemap(rgb: np.ndarray, scale: float) -> np.ndarray:
    """Exposure-normalised Reinhard, then sRGB gamma, so dim and bright probes share one scale."""
    x = rgb / max(scale, 1e-12)
    x = x / (1.0 + x)
    return np.clip(x, 0, 1) ** (1 / 2.2)


def save_contact_sheet(probes: LightFieldProbes, path: str | os.PathLike, *, max_probes: int = 16) -> Path:
    """Write a PNG with each probe's interior maps (borders stripped): reflected radiance, emission,
    normals (as 0.5·n + 0.5), radial distance, irradiance and the moment spread σ = √(E[r²] − E[r]²)
    (the Chebyshev test's uncertainty). Radiance-like maps share one exposure across all probes.

    Returns the path written.
    """
    plt = load_pyplot()

    n = min(int(probes.pos_world.shape[0]), max_probes)
    inner = lambda a: np.asarray(a)[:n, 1:-1, 1:-1]
    rad, emi, nrm = inner(probes.radiance), inner(probes.emission), inner(probes.normal_at(slice(n)))
    dist, irr, mom = inner(probes.distance), inner(probes.irradiance), inner(probes.moments)
    sigma = np.sqrt(np.maximum(mom[..., 1] - mom[..., 0] ** 2, 0.0))
    scale_l = float(np.percentile(np.concatenate([rad.ravel(), emi.ravel()]), 99)) or 1.0
    scale_e = float(np.percentile(irr.ravel(), 99)) or 1.0
    far = float(probes.far)
    dmax = float(np.max(np.where(dist < far, dist, 0.0))) or 1.0

    fig, axes = plt.subplots(n, len(_COLUMNS), figsize=(1.9 * len(_COLUMNS), 1.9 * n + 0.4), squeeze=False)
    pos = np.asarray(probes.pos_world)
    inside = np.asarray(probes.inside)
    for i in range(n):
        images = (
            _tonemap(rad[i], scale_l),
            _tonemap(emi[i], scale_l),
            np.clip(nrm[i] * 0.5 + 0.5, 0, 1),
            np.where(dist[i] < far, dist[i], np.nan),
            _tonemap(irr[i], scale_e),
            sigma[i],
        )
        for j, img in enumerate(images):
            ax = axes[i, j]
            kw = {"cmap": "viridis", "vmin": 0, "vmax": dmax} if img.ndim == 2 else {}
            ax.imshow(img, origin="lower", interpolation="nearest", **kw)
            ax.set_xticks([])
            ax.set_yticks([])
            if i == 0:
                ax.set_title(_COLUMNS[j], fontsize=9)
        label = f"#{i} ({pos[i, 0]:.2f}, {pos[i, 1]:.2f}, {pos[i, 2]:.2f})" + (" INSIDE" if inside[i] else "")
        axes[i, 0].set_ylabel(label, fontsize=7)
    fig.suptitle(f"light-field probes: {n} of {probes.pos_world.shape[0]}, octahedral (+Z axis)", fontsize=10)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
