"""The pictures of one baked probe (NumPy only): its octahedral radiance, distance and normal maps as
8-bit images, and its irradiance on a sphere of directions.

Maps are read from the ``.npz`` that ``probes.save_probes`` writes (layout: ``probes.LightFieldProbes``,
each map with its one-texel border; the border is dropped for display). The geometry maps (distance,
normals) are large (a Sponza 1024-probe bake at 512² holds 2 GB of them), so one probe's row is read
from the archive when it is clicked (:func:`read_npz_row`), never the whole array.
"""

from __future__ import annotations

import math
import os
import zipfile

import numpy as np

from .._core import REC709_LUMA
from ..export import oct_decode, sh_irradiance
from ..scene import srgb8

#: snorm16's largest magnitude: ``_core.maths._packed``'s rule (normal16 = round(oct_encode(n) · 32767)).
_SNORM16 = 32767.0
#: Displayed maps are resized to this many pixels a side: a 16² or 32² map enlarged texel by texel reads as
#: texels in the GUI panel rather than as a browser-smoothed blur, and maps of any size sit side by side.
TILE_PX = 256


def read_npz_row(path: str | os.PathLike, key: str, row: int) -> np.ndarray:
    """Row ``row`` of array ``key`` of an ``.npz`` (C order, as ``np.savez*`` writes), decompressing only
    up to that row."""
    with zipfile.ZipFile(path) as zf, zf.open(f"{key}.npy") as f:
        version = np.lib.format.read_magic(f)
        read_header = (
            np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        )
        shape, fortran, dtype = read_header(f)
        if fortran or not 0 <= row < shape[0]:
            raise ValueError(
                f"{path}:{key}: cannot read row {row} of a {'Fortran' if fortran else ''} {shape} array"
            )
        n_bytes = math.prod(shape[1:]) * dtype.itemsize
        f.seek(f.tell() + row * n_bytes)  # ZipExtFile.seek decompresses forward, keeping nothing
        return np.frombuffer(f.read(n_bytes), dtype).reshape(shape[1:])


def interior(bordered: np.ndarray) -> np.ndarray:
    """A bordered octahedral map without its one-texel border."""
    return bordered[1:-1, 1:-1]


def tile(img: np.ndarray, px: int = TILE_PX) -> np.ndarray:
    """``img`` (uint8, square) resized to ``px`` × ``px``: texel by texel when enlarged (nearest), box-
    averaged when reduced (a 512² geometry map)."""
    from PIL import Image

    if img.shape[0] == px:
        return img
    rule = Image.Resampling.NEAREST if img.shape[0] < px else Image.Resampling.BOX
    return np.asarray(Image.fromarray(img).resize((px, px), rule))


def luminance(rgb: np.ndarray) -> np.ndarray:
    """Rec. 709 luminance of linear RGB (``_core.REC709_LUMA``)."""
    return rgb @ np.array(REC709_LUMA)


def exposure_white(radiance: np.ndarray) -> float:
    """The radiance shown as white: the 99th percentile of the maps' luminance (a few bright texels, the
    light seen directly, clip instead of darkening everything else); 1 when the maps are black."""
    lum = luminance(np.asarray(radiance, np.float64).reshape(-1, 3))
    white = float(np.percentile(lum, 99)) if lum.size else 0.0
    return white if white > 0 and math.isfinite(white) else 1.0


def radiance_image(bordered: np.ndarray, white: float) -> np.ndarray:
    """(R, R, 3) uint8 sRGB of a bordered (R+2)² radiance map, ``white`` mapped to 1 (linear, clipped)."""
    return srgb8(interior(np.asarray(bordered, np.float64)) / white)


def escaped_mask(distance: np.ndarray, far: float) -> np.ndarray:
    """Texels whose ray left the scene: the bake stores ``far`` for them."""
    return distance >= far * (1.0 - 1e-6)


def distance_image(bordered: np.ndarray, far: float) -> np.ndarray:
    """(G, G, 3) uint8: near surfaces bright, the farthest hit black (linear in distance over the probe's
    own range); texels whose ray escaped are blue."""
    d = interior(np.asarray(bordered, np.float64))
    escaped = escaped_mask(d, far)
    hit = d[~escaped]
    top = float(hit.max()) if hit.size else 1.0
    grey = np.round(255.0 * (1.0 - np.clip(d / max(top, 1e-30), 0.0, 1.0))).astype(np.uint8)
    img = np.repeat(grey[..., None], 3, axis=-1)
    img[escaped] = (40, 90, 255)
    return img


def normal_image(normal: np.ndarray, distance: np.ndarray, far: float) -> np.ndarray:
    """(G, G, 3) uint8 of the surface normal each texel's ray hit, world frame, as (n + 1) / 2; black
    where the ray escaped. ``normal``: bordered int16 pairs (format 2, octahedral snorm16) or float
    3-vectors (format 1)."""
    n = interior(np.asarray(normal))
    if n.shape[-1] == 2:
        n = oct_decode(n.astype(np.float64) / _SNORM16)
    rgb = np.round(255.0 * np.clip(0.5 * (np.asarray(n, np.float64) + 1.0), 0.0, 1.0)).astype(np.uint8)
    rgb[escaped_mask(interior(np.asarray(distance)), far)] = 0
    return rgb


def irradiance_colours(sh: np.ndarray, normals: np.ndarray, white: float) -> np.ndarray:
    """(K, 3) uint8 sRGB of a white Lambertian sphere lit by the probe: E(n) / π, from the probe's SH L2
    radiance (``export.sh_irradiance``, Ramamoorthi & Hanrahan 2001), ``white`` mapped to 1."""
    e = sh_irradiance(np.asarray(sh, np.float64)[None], normals)[0]
    return srgb8(np.maximum(e, 0.0) / math.pi / white)
