"""Each probe's share of the evaluation's squared error, per component (pure NumPy; docs/evaluate.md).

A pixel's squared error (mean over RGB, / number of pixels: its part of the MSE) is handed to the probes
that shaded it, so that the probes' shares and what no probe is charged with add up to the component's
MSE exactly (up to float rounding):

* **diffuse indirect**: the pixel's S primary samples share it equally among those with a valid hit
  (the reference is a per-pixel image: no sample carries an error of its own), and each sample hands its
  part to the probes the irradiance blended there in proportion to their normalised weights
  (``probes.irradiance_weights``: McGuire / DDGI weights, trilinear or inverse distance, or the nearest
  usable probe where every weight is 0). A pixel without a valid sample is *unattributed*.
* **glossy indirect**: sample s carries e_s = w_s (L_probe,s − L_ref,s) / S of the pixel's error e_px =
  Σ_s e_s (``_decompose``); the pixel's squared error is shared among its samples in proportion to
  Σ_c |e_s,c| (a sample whose read matched the reference is charged nothing), and a sample's part goes to
  the probe whose radiance its ray read (``GlossyResult.probe``): for a hit, the probe that resolved the
  ray (``glossy_indirect``); for an unresolved ray, the usable probe nearest to its last free point, whose
  radiance the fallback read along the ray (kept apart: ``glossy_indirect_unresolved``, and *unattributed*
  for the probes' glossy colour: no probe resolved that ray); a miss is charged to no probe.

The shares are non-negative, unlike the covariance split of ``_decompose.glossy_terms`` (``by_status``),
which charges a sample its error times the pixel's and may be negative: the two split the same MSE by
different rules, so ``unattributed_glossy_indirect_miss`` is not ``mse_glossy_by_status["miss"]``.
"""

from __future__ import annotations

import numpy as np

from .._core.files import PROBE_ERROR_FORMAT
from ..probes import TraceStatus
from ._decompose import sample_errors


def diffuse_contributions(
    probe_img: np.ndarray,
    ref_img: np.ndarray,
    valid: np.ndarray,
    ids: np.ndarray,
    weights: np.ndarray,
    spp: int,
    n_probes: int,
) -> tuple[np.ndarray, float]:
    """Each probe's part of the diffuse MSE (module docstring).

    Args:
        probe_img, ref_img: (h, w, 3) probe and reference diffuse indirect images.
        valid: (h·w·S,) bool, samples with a valid primary hit (pixel-major).
        ids: (h·w·S, k) probes blended per sample (-1: none).
        weights: (h·w·S, k) their weights (normalised here again in float64).
        spp: samples per pixel S.
        n_probes: length of the result (the baked set's rows).

    Returns:
        ((n_probes,) float64 MSE shares, the unattributed rest); their sum is the MSE.
    """
    d = np.asarray(probe_img, np.float64) - np.asarray(ref_img, np.float64)
    charge_px = np.mean(d * d, axis=-1).reshape(-1) / max(d.shape[0] * d.shape[1], 1)
    n_px = charge_px.size
    valid = np.asarray(valid, bool).reshape(n_px, spp)
    n_valid = valid.sum(axis=1)
    per_sample = np.where(valid, (charge_px / np.maximum(n_valid, 1))[:, None], 0.0).reshape(-1)
    ids = np.asarray(ids).reshape(n_px * spp, -1)
    w = np.where(ids >= 0, np.asarray(weights, np.float64).reshape(ids.shape), 0.0)
    tot = w.sum(axis=1, keepdims=True)
    w = np.divide(w, tot, out=np.zeros_like(w), where=tot > 0)
    charge = per_sample[:, None] * w
    used = ids >= 0
    out = np.bincount(ids[used], weights=charge[used], minlength=n_probes)[:n_probes]
    # pixels with no valid sample, and valid samples no probe shaded (none: the shading falls back)
    rest = float(charge_px[n_valid == 0].sum() + per_sample[tot[:, 0] <= 0].sum())
    return out, rest


def glossy_contributions(
    w: np.ndarray,
    l_probe: np.ndarray,
    l_ref: np.ndarray,
    status: np.ndarray,
    probe: np.ndarray,
    spp: int,
    n_probes: int,
) -> dict:
    """Each probe's part of the glossy MSE (module docstring).

    Args:
        w: (n, 3) estimator weights (0 where a sample has no glossy ray).
        l_probe, l_ref: (n, 3) radiance read from the probes and the CRN reference's.
        status: (n,) tracer status (``probes.TraceStatus``; other values: no ray).
        probe: (n,) the probe read (-1: none).
        spp: samples per pixel S (n = pixels × S, pixel-major).
        n_probes: length of the per-probe arrays.

    Returns:
        ``hit`` and ``unresolved`` ((n_probes,) float64: rays the probe resolved; unresolved rays read
        from it as the nearest probe), ``miss`` and ``other`` (floats: misses; rays with no probe read);
        their total is the glossy MSE.
    """
    e_s, e_px = sample_errors(w, l_probe, l_ref, spp)
    n_px = e_px.shape[0]
    charge_px = np.mean(e_px * e_px, axis=1) / max(n_px, 1)
    a = np.abs(e_s).sum(axis=1).reshape(n_px, spp)
    a_tot = a.sum(axis=1, keepdims=True)
    share = np.divide(a, a_tot, out=np.zeros_like(a), where=a_tot > 0)
    charge = (share * charge_px[:, None]).reshape(-1)
    status, probe = np.asarray(status).reshape(-1), np.asarray(probe).reshape(-1)
    has = probe >= 0
    hit, unres = has & (status == TraceStatus.HIT), has & (status == TraceStatus.UNRESOLVED)
    count = lambda m: np.bincount(probe[m], weights=charge[m], minlength=n_probes)[:n_probes]
    return {
        "hit": count(hit),
        "unresolved": count(unres),
        "miss": float(charge[status == TraceStatus.MISS].sum()),
        "other": float(charge[~hit & ~unres & (status != TraceStatus.MISS)].sum()),
    }


def probe_error(lf_pos, prim, shading, probe_d, ref_d, crn_radiance) -> dict[str, np.ndarray] | None:
    """The arrays of ``probe_error.npz`` (docs/evaluate.md), or None when ``shading`` did not record which
    probes shaded each sample."""
    if shading.probe is None or shading.diffuse_ids is None:
        return None
    pos = np.asarray(lf_pos, np.float32).reshape(-1, 3)
    n = len(pos)
    dif, dif_rest = diffuse_contributions(
        probe_d, ref_d, prim.valid, shading.diffuse_ids, shading.diffuse_weights, prim.spp, n
    )
    gl = glossy_contributions(
        prim.w_glossy, shading.glossy, crn_radiance, shading.status, shading.probe, prim.spp, n
    )
    f = lambda v: np.asarray(v, np.float64)
    return {
        "format": np.asarray(PROBE_ERROR_FORMAT),
        "pos_world": pos,
        "diffuse_indirect": dif,
        "glossy_indirect": gl["hit"],
        "glossy_indirect_unresolved": gl["unresolved"],
        "unattributed_diffuse_indirect": f(dif_rest),
        "unattributed_glossy_indirect_miss": f(gl["miss"]),
        "unattributed_glossy_indirect_unresolved": f(gl["unresolved"].sum()),
        "unattributed_glossy_indirect_other": f(gl["other"]),
    }
