"""A tiny finished run folder for the viewer's tests, written directly (no placement, bake or render):
four probes in the built-in Cornell box, a synthetic ``probes_baked.npz`` whose maps are closed-form
values the tests can predict, and an ``eval/`` folder with one small error image.

Probe 0 and 2 are usable, probe 1 is flagged inside geometry by the bake, probe 3 is inactive in
probes.json; the bake pads the set to 8 rows with inactive copies of probe 3 (as ``bake.pad_pow2`` does).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image

POSITIONS = np.array(
    [[150.0, 450.0, 150.0], [400.0, 450.0, 150.0], [278.0, 450.0, 350.0], [150.0, 100.0, 100.0]], np.float32
)
ACTIVE = np.array([True, True, True, False])
INSIDE = np.array([False, True, False, False])
N_ROWS = 8  # the bake's power-of-two padding
RADIANCE_RES, GEOMETRY_RES, MOMENTS_RES, IRRADIANCE_RES = 16, 8, 4, 2
#: constant reflected radiance of probe i (grey): 0.1 (i + 1)
RADIANCE = 0.1 * (np.arange(N_ROWS) + 1.0)
#: constant filtered distance E[r] of probe i
REACH = 50.0 * (np.arange(N_ROWS) + 1.0)
FAR = 1.0e4
EVAL_W, EVAL_H = 8, 6


def distance_map(i: int) -> np.ndarray:
    """Probe i's bordered distance map: 10 i + 1 + texel number, escaped (``FAR``) in the first row."""
    g = GEOMETRY_RES + 2
    d = 10.0 * i + 1.0 + np.arange(g * g, dtype=np.float32).reshape(g, g)
    d[1, :] = FAR
    return d


def write_npz(path: Path) -> Path:
    n, r, g = N_ROWS, RADIANCE_RES + 2, GEOMETRY_RES + 2
    pos = np.concatenate([POSITIONS, np.repeat(POSITIONS[-1:], n - len(POSITIONS), axis=0)])
    emission = np.zeros((n, r, r, 3), np.float32)
    emission[1, 2, 2] = 5.0  # on the unusable probe: the exposure (usable probes only) must not see it
    moments = np.zeros((n, MOMENTS_RES + 2, MOMENTS_RES + 2, 2), np.float32)
    moments[..., 0] = REACH[:, None, None]
    moments[..., 1] = REACH[:, None, None] ** 2
    np.savez_compressed(
        path,
        pos_world=pos,
        active=np.concatenate([ACTIVE, np.zeros(n - len(ACTIVE), bool)]),
        inside=np.concatenate([INSIDE, np.zeros(n - len(INSIDE), bool)]),
        radiance=np.broadcast_to(RADIANCE[:, None, None, None], (n, r, r, 3)).astype(np.float32),
        emission=emission,
        normal16=np.zeros((n, g, g, 2), np.int16),  # octahedral uv (0, 0): every normal is +z
        distance=np.stack([distance_map(i) for i in range(n)]),
        irradiance=np.ones((n, IRRADIANCE_RES + 2, IRRADIANCE_RES + 2, 3), np.float32),
        moments=moments,
        far=np.float32(FAR),
        format=np.asarray("probeplace.LightFieldProbes/2"),
        bake_settings=np.asarray(json.dumps({"version": 2, "scene": "cornell_box"})),
    )
    return path


def write_probes_json(path: Path, positions=POSITIONS, active=ACTIVE, metadata=None) -> Path:
    meta = {
        "method": "grid",
        "coverage": 0.9,
        "valid_space": {"n_relocated": 0},
        "budget_fit": {"n_filled": 0},
    }
    doc = {
        "format": "probeplace.ProbeSet/1",
        "method": "grid",
        "units_m": 0.001,
        "up_axis": "+Y",
        "handedness": "right",
        "positions": np.asarray(positions).tolist(),
        "active": np.asarray(active).tolist(),
        "metadata": meta if metadata is None else metadata,
    }
    path.write_text(json.dumps(doc))
    return path


def write_run(folder: Path, *, bake: bool = True, evaluation: bool = True) -> Path:
    """The run folder (``DONE`` last, as the runner writes it)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "config.yaml").write_text("name: viewtest\nscene:\n  name: cornell_box\n")
    write_probes_json(folder / "probes.json")
    if bake:
        write_npz(folder / "probes_baked.npz")
    if evaluation:
        ev = folder / "eval"
        ev.mkdir()
        err = np.zeros((EVAL_H, EVAL_W + 3, 3), np.uint8)
        err[:, :EVAL_W] = (250, 10, 10)  # the image; the 3 columns after it stand for the colour bar
        Image.fromarray(err).save(ev / "error_full_false.png")
        metrics = {"view": "front", "width": EVAL_W, "height": EVAL_H, "error_png_vmax": {"full": 0.25}}
        (ev / "metrics.json").write_text(json.dumps(metrics))
    (folder / "DONE").write_text("ok\n")
    return folder
