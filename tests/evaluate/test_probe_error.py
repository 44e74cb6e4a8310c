"""Each probe's share of the evaluation's error (``evaluate._attribute``) on hand-made cases.

Oracles: shares worked out by hand on a two-pixel image, a slow per-sample loop over random samples (the
rule of the module docstring written out, not vectorised), and the invariant that the probes' shares and
the unattributed rest add up to the component's MSE.
"""

from __future__ import annotations

import numpy as np
import pytest

from probeplace.evaluate import diffuse_contributions, glossy_contributions


def test_diffuse_shares_by_hand():
    # 1 × 2 image, S = 2. Pixel 0: error (0.2, 0.2, 0.2) → squared 0.04, / 2 pixels = 0.02; its two samples
    # are valid and get 0.01 each: sample 0 blends probes 0 and 1 (weights 1 and 3 → 0.25 / 0.75), sample 1
    # probe 2 alone. Pixel 1: error 0.1 → 0.005 to share, but no valid sample: unattributed.
    probe = np.array([[[0.5, 0.5, 0.5], [0.1, 0.1, 0.1]]])
    ref = np.array([[[0.3, 0.3, 0.3], [0.0, 0.0, 0.0]]])
    valid = np.array([True, True, False, False])
    ids = np.array([[0, 1], [2, -1], [-1, -1], [-1, -1]])
    w = np.array([[1.0, 3.0], [0.7, 0.0], [0.0, 0.0], [0.0, 0.0]])
    shares, rest = diffuse_contributions(probe, ref, valid, ids, w, spp=2, n_probes=4)
    np.testing.assert_allclose(shares, [0.0025, 0.0075, 0.01, 0.0], rtol=1e-12)
    assert rest == pytest.approx(0.005, rel=1e-12)
    mse = float(np.mean((probe - ref) ** 2))
    assert shares.sum() + rest == pytest.approx(mse, rel=1e-12)


def test_glossy_shares_by_hand():
    # One pixel, S = 4, weight 1: e_s = (L_probe − L_ref) / 4 per sample = 0.1, 0.3, 0, 0.1 (grey), so
    # e_px = 0.5, MSE 0.25; shares by |e_s|: 0.2, 0.6, 0, 0.2. Sample 0 hit probe 1, sample 1 unresolved
    # read from probe 0, sample 2 hit probe 1 with no error, sample 3 missed.
    w = np.ones((4, 3))
    lp = np.array([0.4, 1.2, 0.5, 0.4])[:, None] * np.ones(3)
    lr = np.array([0.0, 0.0, 0.5, 0.0])[:, None] * np.ones(3)
    status = np.array([1, 2, 1, 0])
    probe = np.array([1, 0, 1, -1])
    g = glossy_contributions(w, lp, lr, status, probe, spp=4, n_probes=2)
    np.testing.assert_allclose(g["hit"], [0.0, 0.25 * 0.2], rtol=1e-12)
    np.testing.assert_allclose(g["unresolved"], [0.25 * 0.6, 0.0], rtol=1e-12)
    assert g["miss"] == pytest.approx(0.25 * 0.2, rel=1e-12)
    assert g["other"] == 0.0


def _slow_glossy(w, lp, lr, status, probe, spp, n_probes):
    """The rule written out sample by sample."""
    out = {"hit": np.zeros(n_probes), "unresolved": np.zeros(n_probes), "miss": 0.0, "other": 0.0}
    n_px = len(w) // spp
    for px in range(n_px):
        e = [w[i] * (lp[i] - lr[i]) / spp for i in range(px * spp, (px + 1) * spp)]
        e_px = sum(e)
        charge = float(np.mean(e_px**2)) / n_px
        a = [float(np.abs(x).sum()) for x in e]
        if sum(a) == 0:
            continue
        for j, i in enumerate(range(px * spp, (px + 1) * spp)):
            c = charge * a[j] / sum(a)
            if probe[i] >= 0 and status[i] == 1:
                out["hit"][probe[i]] += c
            elif probe[i] >= 0 and status[i] == 2:
                out["unresolved"][probe[i]] += c
            elif status[i] == 0:
                out["miss"] += c
            else:
                out["other"] += c
    return out


def _slow_diffuse(probe, ref, valid, ids, w, spp, n_probes):
    out, rest = np.zeros(n_probes), 0.0
    n_px = probe.shape[0] * probe.shape[1]
    d = (probe - ref).reshape(n_px, 3)
    for px in range(n_px):
        charge = float(np.mean(d[px] ** 2)) / n_px
        samples = [i for i in range(px * spp, (px + 1) * spp) if valid[i]]
        if not samples:
            rest += charge
            continue
        for i in samples:
            tot = sum(w[i][j] for j in range(ids.shape[1]) if ids[i][j] >= 0)
            for j in range(ids.shape[1]):
                if ids[i][j] >= 0:
                    out[ids[i][j]] += charge / len(samples) * w[i][j] / tot
    return out, rest


@pytest.mark.parametrize("seed", [0, 1])
def test_shares_match_a_slow_loop_and_add_up(seed):
    rng = np.random.default_rng(seed)
    h, wd, spp, n_probes, k = 3, 4, 5, 6, 3
    n = h * wd * spp
    # glossy: some samples with no ray (weight 0, status -1), every status, a probe read or not
    w = rng.uniform(0, 2, (n, 3)) * (rng.uniform(size=(n, 1)) > 0.2)
    status = np.where(w[:, 0] > 0, rng.integers(0, 3, n), -1)
    probe = np.where(status > 0, rng.integers(0, n_probes, n), -1)
    probe[rng.uniform(size=n) < 0.05] = -1  # a ray with no probe read ("other" unless it missed)
    lp, lr = rng.uniform(0, 1, (n, 3)), rng.uniform(0, 1, (n, 3))
    g = glossy_contributions(w, lp, lr, status, probe, spp, n_probes)
    slow = _slow_glossy(w, lp, lr, status, probe, spp, n_probes)
    for key in ("hit", "unresolved", "miss", "other"):
        np.testing.assert_allclose(g[key], slow[key], rtol=1e-10, atol=1e-16)  # float64, reordered sums
    e_px = (w * (lp - lr) / spp).reshape(h * wd, spp, 3).sum(axis=1)
    mse = float(np.mean(e_px**2))
    total = g["hit"].sum() + g["unresolved"].sum() + g["miss"] + g["other"]
    assert total == pytest.approx(mse, rel=1e-12)
    # diffuse: invalid samples and empty slots
    valid = rng.uniform(size=n) > 0.3
    ids = np.where(rng.uniform(size=(n, k)) > 0.3, rng.integers(0, n_probes, (n, k)), -1)
    ids[:, 0] = rng.integers(0, n_probes, n)  # every valid sample has a probe (the shading falls back)
    wt = rng.uniform(0.01, 1, (n, k))
    probe_img, ref_img = rng.uniform(0, 1, (h, wd, 3)), rng.uniform(0, 1, (h, wd, 3))
    shares, rest = diffuse_contributions(probe_img, ref_img, valid, ids, wt, spp, n_probes)
    slow_s, slow_r = _slow_diffuse(probe_img, ref_img, valid, ids, wt, spp, n_probes)
    np.testing.assert_allclose(shares, slow_s, rtol=1e-10)
    assert rest == pytest.approx(slow_r, rel=1e-10, abs=1e-16)
    assert shares.sum() + rest == pytest.approx(float(np.mean((probe_img - ref_img) ** 2)), rel=1e-12)
