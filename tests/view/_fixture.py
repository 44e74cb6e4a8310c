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


#: the per-probe files of a run of this version (``detail=True``): probe 2 relocated, probe 0 filled
DETAIL_META = {
    "method": "grid",
    "coverage": 0.8,
    "valid_space": {"n_relocated": 1},
    "budget_fit": {"n_filled": 1},
    "relocated_probes": [2],
    "projected_probes": [],
    "filled_probes": [0],
}
SEEN = np.array([10, 0, 5, 3])
UNIQUE = np.array([4, 0, 1, 0])
N_COVERABLE = 20
UNCOVERED = np.array([[100.0, 0.5, 100.0], [200.0, 0.5, 300.0], [300.0, 548.0, 200.0]], np.float32)
#: each baked row's share of the diffuse / glossy MSE (rows 4-7 are padding: charged nothing)
DIFFUSE_SHARE = np.array([0.002, 0.0, 0.006, 0.0, 0, 0, 0, 0])
GLOSSY_SHARE = np.array([0.0, 0.0, 3e-5, 0.0, 0, 0, 0, 0])
MSE = {"diffuse_indirect": 0.01, "glossy_indirect": 5e-5}


def write_detail(folder: Path, *, evaluation: bool = True) -> None:
    """``probes.coverage.npz`` beside probes.json and, with ``evaluation``, ``eval/probe_error.npz``."""
    np.savez_compressed(
        folder / "probes.coverage.npz",
        format=np.asarray("probeplace.CoverageDetail/1"),
        seen=SEEN,
        unique=UNIQUE,
        n_multiple=np.asarray(5),
        uncovered=np.arange(3),
        uncovered_pos=UNCOVERED,
        uncovered_normal=np.tile(np.float32([0, 1, 0]), (3, 1)),
        n_samples=np.asarray(24),
        n_coverable=np.asarray(N_COVERABLE),
        coverage=np.asarray(0.8),
    )
    if evaluation:
        pos = np.concatenate([POSITIONS, np.repeat(POSITIONS[-1:], N_ROWS - len(POSITIONS), axis=0)])
        np.savez_compressed(
            folder / "eval" / "probe_error.npz",
            format=np.asarray("probeplace.ProbeError/1"),
            pos_world=pos,
            diffuse_indirect=DIFFUSE_SHARE,
            glossy_indirect=GLOSSY_SHARE,
            glossy_indirect_unresolved=np.zeros(N_ROWS),
            unattributed_diffuse_indirect=np.asarray(MSE["diffuse_indirect"] - DIFFUSE_SHARE.sum()),
            unattributed_glossy_indirect_miss=np.asarray(MSE["glossy_indirect"] - GLOSSY_SHARE.sum()),
            unattributed_glossy_indirect_unresolved=np.asarray(0.0),
            unattributed_glossy_indirect_other=np.asarray(0.0),
            mse_diffuse_indirect=np.asarray(MSE["diffuse_indirect"]),
            mse_glossy_indirect=np.asarray(MSE["glossy_indirect"]),
        )


def write_run(folder: Path, *, bake: bool = True, evaluation: bool = True, detail: bool = False) -> Path:
    """The run folder (``DONE`` last, as the runner writes it); ``detail``: with the per-probe files of
    this version (:func:`write_detail`, :data:`DETAIL_META`)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "config.yaml").write_text("name: viewtest\nscene:\n  name: cornell_box\n")
    write_probes_json(folder / "probes.json", metadata=DETAIL_META if detail else None)
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
    if detail:
        write_detail(folder, evaluation=evaluation)
    (folder / "DONE").write_text("ok\n")
    return folder
