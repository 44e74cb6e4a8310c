"""Images on disk: float EXR (OpenEXR) for data, tone-mapped sRGB PNG (Pillow) for looking at.

EXR layout: one file, one channel group per layer: ``RGB`` for the main image plus ``<layer>.RGB``
for the others (e.g. ``direct.RGB``, ``direct_var.RGB``), 32-bit float, ZIP compression, written
atomically (``_core.write_exr``).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from jaxtyping import Array, Float
from PIL import Image

from .._core import read_exr, write_exr
from ..scene import srgb8
from ._render import RenderResult


def _check_rgb(name: str, img) -> np.ndarray:
    a = np.asarray(img, np.float32)
    if a.ndim != 3 or a.shape[-1] != 3:
        raise ValueError(f"image {name!r} must have shape (h, w, 3), got {a.shape}")
    return np.ascontiguousarray(a)


def save_exr(
    path: str | Path, layers: Mapping[str, Float[Array, "h w 3"] | np.ndarray], main: str = ""
) -> Path:
    """Write float32 RGB layers to one EXR; layer ``main`` (or the first) becomes the default ``RGB``.

    Returns the path written. Raises ValueError on a non-(h, w, 3) layer or layers of different sizes.
    """
    if not layers:
        raise ValueError("save_exr needs at least one layer")
    main = main or next(iter(layers))
    channels = {}
    shape = None
    for name, img in layers.items():
        a = _check_rgb(name, img)
        if shape is not None and a.shape != shape:
            raise ValueError(f"layer {name!r} has shape {a.shape}, others {shape}")
        shape = a.shape
        channels["RGB" if name == main else f"{name}.RGB"] = a
    return write_exr(path, channels)


def load_exr(path: str | Path) -> dict[str, np.ndarray]:
    """Read an EXR written by :func:`save_exr`: layer name (``""`` for the main one) → (h, w, 3) float32."""
    channels = read_exr(path, separate_channels=False)
    return {"" if name == "RGB" else name.removesuffix(".RGB"): v for name, v in channels.items()}


def tonemap(rgb: Float[Array, "h w 3"] | np.ndarray, exposure: float = 0.0) -> np.ndarray:
    """Linear radiance → 8-bit sRGB: scale by 2^exposure, clip to [0, 1], sRGB transfer function
    (IEC 61966-2-1), round. NaN and negative values map to 0."""
    a = np.nan_to_num(np.asarray(rgb, np.float64), nan=0.0, posinf=1.0, neginf=0.0) * 2.0**exposure
    return srgb8(a)


def save_png(path: str | Path, rgb: Float[Array, "h w 3"] | np.ndarray, exposure: float = 0.0) -> Path:
    """Write a tone-mapped PNG (see :func:`tonemap`). Returns the path written."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(tonemap(_check_rgb("rgb", rgb), exposure)).save(path)
    return path


def save_render(result: RenderResult, stem: str | Path, exposure: float = 0.0) -> tuple[Path, Path]:
    """Save a render as ``<stem>.exr`` (every component and its ``_var`` variance-of-mean layer; the
    main layer is ``full``) and ``<stem>.png`` (the tone-mapped full image). Returns both paths."""
    layers = {}
    for i, name in enumerate(result.components):
        layers[name] = result.mean[i]
    for i, name in enumerate(result.components):
        layers[f"{name}_var"] = result.var_of_mean[i]
    stem = Path(stem)
    exr = save_exr(stem.with_suffix(".exr"), layers, main="full")
    png = save_png(stem.with_suffix(".png"), result.image("full"), exposure)
    return exr, png
