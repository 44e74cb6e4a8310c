"""Write an evaluation: ``metrics.json`` (atomic), EXR + PNG images and false-colour error maps.

The files are written into a hidden folder beside ``out`` and moved in only when all of them were
written, ``metrics.json`` last (its presence marks a finished evaluation); a failed write (a full disk)
leaves nothing behind but what ``out`` held before.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

from .._core import write_atomic, write_json_atomic
from .._core.files import PROBE_ERROR_FILE, RunFiles
from ..render import save_exr, save_png
from ._evaluate import EVAL_IMAGES, EvalResult
from ._metrics import EVAL_COMPONENTS

# Per-file allowance for headers, metadata and the file system's block rounding, bytes.
_FILE_OVERHEAD = 8192


def evaluation_bytes(width: int, height: int, n_probes: int = 0) -> int:
    """An upper bound on the bytes :func:`write_evaluation` writes for a ``width`` × ``height`` image:
    one 8-bit RGB PNG per image (zlib never grows data by more than ~0.03 %, so ≤ 3.01 bytes a pixel plus
    the row filter byte), the false-colour maps (with their colour bar: ≤ 1.2× the width), and one EXR
    holding every image as float32 RGB (12 bytes a pixel, uncompressed), plus per-file overhead; and
    ``probe_error.npz``: 36 bytes a probe (three float64 shares and a float32 position), a 2 KiB
    allowance for its zip and array headers and scalars, and the file overhead."""
    px = int(width) * int(height)
    png = int(px * 3.01) + int(height) + _FILE_OVERHEAD
    false_png = int(1.2 * px * 3.01) + int(height) + _FILE_OVERHEAD
    exr = 12 * px * len(EVAL_IMAGES) + _FILE_OVERHEAD
    shares = int(36 * int(n_probes) * 1.01) + 2048 + _FILE_OVERHEAD
    return len(EVAL_IMAGES) * png + len(EVAL_COMPONENTS) * false_png + exr + shares + _FILE_OVERHEAD


# Viridis at 9 stops (matplotlib's table, sampled), interpolated linearly: perceptually ordered.
_VIRIDIS = np.array(
    [
        [0.267, 0.005, 0.329],
        [0.279, 0.175, 0.483],
        [0.230, 0.322, 0.546],
        [0.173, 0.449, 0.558],
        [0.128, 0.567, 0.551],
        [0.158, 0.684, 0.502],
        [0.369, 0.789, 0.383],
        [0.678, 0.864, 0.190],
        [0.993, 0.906, 0.144],
    ]
)


def false_colour(err: np.ndarray, vmax: float | None = None, *, bar: bool = True) -> np.ndarray:
    """Luminance-free error magnitude (mean over RGB) → 8-bit viridis RGB, 0 … ``vmax`` (default: the
    99th percentile); with ``bar`` a vertical colour bar (bottom 0, top ``vmax``) is appended."""
    e = np.asarray(err, np.float64)
    e = e.mean(axis=-1) if e.ndim == 3 else e
    if vmax is None:
        vmax = float(np.percentile(e, 99)) if e.size else 1.0
    vmax = vmax if vmax > 0 else 1.0
    t = np.clip(np.nan_to_num(e / vmax), 0.0, 1.0)

    def cmap(x):
        f = x * (len(_VIRIDIS) - 1)
        i = np.clip(np.floor(f).astype(int), 0, len(_VIRIDIS) - 2)
        a = (f - i)[..., None]
        return _VIRIDIS[i] * (1 - a) + _VIRIDIS[i + 1] * a

    rgb = cmap(t)
    if bar:
        h = e.shape[0]
        ramp = np.linspace(1.0, 0.0, h)[:, None] * np.ones((1, max(4, e.shape[1] // 16)))
        gap = np.ones((h, 2, 3))
        rgb = np.concatenate([rgb, gap, cmap(ramp)], axis=1)
    return np.round(rgb * 255).astype(np.uint8)


def write_evaluation(result: EvalResult, out_dir: str | os.PathLike) -> dict[str, Path]:
    """Write ``metrics.json``, ``images.exr`` (every image as a layer), one tone-mapped PNG per image,
    ``error_<component>_false.png`` (viridis, colour bar on the right, scale in metrics.json under
    ``error_png_vmax``) and ``probe_error.npz`` (each probe's share of the error, when the result has
    it) into ``out_dir``, all or nothing (module docstring). Returns name → path."""
    out = Path(out_dir)
    made = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    try:
        staged = _write_files(result, stage)
        (out / RunFiles.metrics).unlink(missing_ok=True)  # an earlier evaluation's: unfinished until the end
        # metrics.json last: an interrupted move leaves an evaluation without it, i.e. unfinished
        names = sorted(staged, key=lambda k: k == "metrics")
        for k in names:
            os.replace(staged[k], out / staged[k].name)
        return {k: out / staged[k].name for k in staged}
    except BaseException:
        if made and out.is_dir() and not any(out.iterdir()):
            out.rmdir()
        raise
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def _write_files(result: EvalResult, out: Path) -> dict[str, Path]:
    """Every file of :func:`write_evaluation` into the (staging) folder ``out``."""
    paths: dict[str, Path] = {}
    vmax = {}
    for c in EVAL_COMPONENTS:
        err = result.images[f"error_{c}"]
        v = float(np.percentile(np.asarray(err).mean(axis=-1), 99)) if np.asarray(err).size else 0.0
        vmax[c] = v
        p = out / f"error_{c}_false.png"
        Image.fromarray(false_colour(err, v if v > 0 else None)).save(p)
        paths[f"error_{c}_false"] = p
    for name, img in result.images.items():
        paths[name] = save_png(out / f"{name}.png", img)
    paths["exr"] = save_exr(out / RunFiles.images, result.images, main="probe_full")
    if result.probe_error is not None:  # each probe's share of the error (_attribute)
        arrays = result.probe_error
        paths["probe_error"] = write_atomic(
            out / PROBE_ERROR_FILE, lambda f: np.savez_compressed(f, **arrays)
        )
    metrics = dict(result.metrics)
    metrics["error_png_vmax"] = vmax
    paths["metrics"] = write_json_atomic(out / RunFiles.metrics, metrics)
    return paths
