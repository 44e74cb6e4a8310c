"""DDGI-style probe texture atlases (Majercik et al. 2019, "Dynamic Diffuse Global Illumination with
Ray-Traced Irradiance Fields", JCGT 8(2), §3): an irradiance atlas and a distance-moment atlas, one
tile per probe, each tile an octahedral map with a one-texel border so hardware bilinear filtering is
correct across the octahedral fold (Luo 2022 §4.3.5).

Files written for ``--out probes_ddgi.json``::

    probes_ddgi.json                 sidecar: layout, conventions, probe positions
    probes_ddgi.irradiance.exr       RGB float32, tile (I+2)²  (DDGI's usual I = 6 → 8×8 tiles)
    probes_ddgi.distance.exr         R = E[r], G = E[r²] float32, tile (D+2)²  (usual D = 14 → 16×16)
    probes_ddgi.irradiance.png       8-bit preview: x / (1 + x) tone map, sRGB
    probes_ddgi.distance.png         8-bit preview: E[r] / far

Tiles are laid out row-major, ``tiles_per_row = ceil(sqrt(n))``: probe k (k-th *active* probe) at
tile column k mod tiles_per_row, tile row k div tiles_per_row; atlas pixel row 0 is the top of the
image. Inside a tile, texel (row i, column j) of the interior is at (i+1, j+1) and holds the octahedral
direction of u = (j+½)·2/N − 1, v = (i+½)·2/N − 1 decoded with probeplace's convention (octahedron axis
= world +Z, ``probeplace._core._octahedral``).

Irradiance is the cosine-convolved incident light E(n) = ∫ L(ω) max(0, n·ω) dω (W m⁻²) for a receiver
normal n (divide by π for the outgoing radiance of a white Lambertian surface), from the baked radiance
(``light="total"``: reflected + emitted/sky, what DDGI's probes see; ``"reflected"``: the baked
``irradiance`` map). Distance moments are the baked cosine-power-filtered moments, bilinearly resampled
when the tile size differs from the bake.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from .._core.files._io import write_bytes_atomic, write_exr, write_json_atomic
from ._data import ExportError, ExportProbes
from ._io_util import f32_list
from ._octa import add_border, resample_bordered, texel_directions, texel_solid_angles

DDGI_FORMAT = "probeplace.DDGIAtlas/1"


def cosine_irradiance(bordered_radiance: np.ndarray, res: int) -> np.ndarray:
    """(P, R+2, R+2, 3) bordered radiance → (P, res+2, res+2, 3) bordered irradiance E(n) (quadrature
    over the source texels with their exact solid angles, as ``probes._filter.irradiance_map``)."""
    r = bordered_radiance.shape[-2] - 2
    interior = np.asarray(bordered_radiance, np.float64)[:, 1:-1, 1:-1].reshape(-1, r * r, 3)
    omega = texel_directions(r).reshape(-1, 3)
    w = np.maximum(texel_directions(res).reshape(-1, 3) @ omega.T, 0.0) * texel_solid_angles(r).reshape(-1)
    e = np.einsum("mk,pkc->pmc", w, interior).reshape(-1, res, res, 3)
    return add_border(e)


def pack_atlas(tiles: np.ndarray) -> tuple[np.ndarray, int]:
    """(P, T, T, C) tiles → (rows·T, cols·T, C) atlas (zeros in unused slots), tiles_per_row."""
    p, t = tiles.shape[0], tiles.shape[1]
    cols = max(1, math.ceil(math.sqrt(p)))
    rows = max(1, math.ceil(p / cols))
    atlas = np.zeros((rows * t, cols * t, tiles.shape[-1]), tiles.dtype)
    for k in range(p):
        r, c = divmod(k, cols)
        atlas[r * t : (r + 1) * t, c * t : (c + 1) * t] = tiles[k]
    return atlas, cols


def unpack_atlas(atlas: np.ndarray, n: int, tile: int, cols: int) -> np.ndarray:
    """Inverse of :func:`pack_atlas` for the first ``n`` tiles."""
    out = np.empty((n, tile, tile, atlas.shape[-1]), atlas.dtype)
    for k in range(n):
        r, c = divmod(k, cols)
        out[k] = atlas[r * tile : (r + 1) * tile, c * tile : (c + 1) * tile]
    return out


def _png(path: Path, rgb01: np.ndarray) -> None:
    import io

    from PIL import Image

    lin = np.maximum(rgb01, 0.0031308)  # sRGB transfer curve, IEC 61966-2-1
    srgb = np.where(rgb01 <= 0.0031308, 12.92 * rgb01, 1.055 * np.power(lin, 1 / 2.4) - 0.055)
    img = Image.fromarray(np.round(np.clip(srgb, 0, 1) * 255).astype(np.uint8))
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    write_bytes_atomic(path, buf.getvalue())


def write_ddgi(
    probes: ExportProbes,
    out: str | os.PathLike,
    *,
    irradiance_res: int = 6,
    distance_res: int = 14,
    light: str = "total",
) -> list[Path]:
    """Write the atlases (EXR + PNG previews) and the JSON sidecar ``out`` (module docstring).

    Args:
        probes: needs baked maps (``probes.maps``: read a ``.npz`` from ``probeplace bake``).
        out: the sidecar path (``.json``); the images are written beside it.
        irradiance_res, distance_res: interior tile sizes (DDGI's usual 6 and 14: 8² and 16² tiles).
        light: ``"total"`` or ``"reflected"`` (module docstring).
    """
    out = Path(out)
    if out.suffix != ".json":
        raise ExportError(f"the DDGI export's --out is its JSON sidecar (.json), got {out}")
    act = probes.active_only()
    if act.maps is None:
        raise ExportError("DDGI textures need baked probes: export a .npz written by the bake step")
    if irradiance_res < 1 or distance_res < 1:
        raise ExportError("tile resolutions must be >= 1")
    if light == "total":
        if act.maps.radiance is None or act.maps.emission is None:
            raise ExportError("light='total' needs the baked radiance and emission maps")
        irr = cosine_irradiance(act.maps.radiance + act.maps.emission, irradiance_res)
    elif light == "reflected":
        irr = resample_bordered(act.maps.irradiance.astype(np.float64), irradiance_res)
    else:
        raise ExportError(f"light must be 'total' or 'reflected', got {light!r}")
    mom = resample_bordered(act.maps.moments.astype(np.float64), distance_res)
    irr_atlas, cols = pack_atlas(irr.astype(np.float32))
    mom_atlas, _ = pack_atlas(mom.astype(np.float32))
    stem = out.name[: -len(".json")]
    names = {k: f"{stem}.{k}" for k in ("irradiance.exr", "distance.exr", "irradiance.png", "distance.png")}
    d = out.parent
    d.mkdir(parents=True, exist_ok=True)
    write_exr(d / names["irradiance.exr"], {"RGB": irr_atlas})
    write_exr(d / names["distance.exr"], {"R": mom_atlas[..., 0], "G": mom_atlas[..., 1]})
    _png(d / names["irradiance.png"], irr_atlas / (1.0 + irr_atlas))
    far = act.maps.far
    _png(d / names["distance.png"], np.repeat(mom_atlas[..., :1] / far, 3, axis=-1))
    sidecar = {
        "format": DDGI_FORMAT,
        "method": probes.method,
        "units_m": probes.units_m,
        "up_axis": "+Y",
        "handedness": "right",
        "probe_count": act.n,
        "positions": f32_list(act.positions),
        "source_rows": np.flatnonzero(probes.active).tolist(),
        "inside": None if act.inside is None else act.inside.tolist(),
        "far": far,
        "tiles_per_row": cols,
        "tile_order": "row-major: probe k at tile (row k // tiles_per_row, column k % tiles_per_row)",
        "octahedral": {
            "axis": "+Z",
            "uv": "u = (col + 0.5) * 2 / N - 1, v = (row + 0.5) * 2 / N - 1 inside the border",
            "border": 1,
            "reference": "Cigolle et al. 2014 Listing 6; probeplace._core._octahedral",
        },
        "irradiance": {
            "file": names["irradiance.exr"],
            "preview": names["irradiance.png"],
            "interior_res": irradiance_res,
            "tile_res": irradiance_res + 2,
            "channels": "RGB float32: irradiance E(n) W/m^2 (divide by pi for Lambertian radiance)",
            "light": light,
            "size": list(irr_atlas.shape[:2]),
        },
        "distance": {
            "file": names["distance.exr"],
            "preview": names["distance.png"],
            "interior_res": distance_res,
            "tile_res": distance_res + 2,
            "channels": "R = E[r], G = E[r^2] (cosine-power filtered radial distance, scene units)",
            "size": list(mom_atlas.shape[:2]),
        },
    }
    written = [d / names[k] for k in names]
    return [write_json_atomic(out, sidecar), *written]
