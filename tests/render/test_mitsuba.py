"""Cross-check against Mitsuba 3 (external oracle): the Cornell box rendered by both agrees within noise.

The bound comes from both images' variance estimates: ours from the per-pixel sample variance, Mitsuba's
from the spread of ``N_SEEDS`` independent renders. Pixels are averaged over 4×4 blocks so both variance
estimates are themselves precise; the block z-scores must look standard normal.
"""

from __future__ import annotations

import jax
import numpy as np
import pytest

from probeplace.render import RenderConfig, render

mi = pytest.importorskip("mitsuba")

N_SEEDS = 8


def _mitsuba_mean_var(scene, view, *, size, spp, max_depth, tmp_path):
    from probeplace.render import best_mitsuba_variant, mitsuba_scene_dict

    best_mitsuba_variant()
    d = mitsuba_scene_dict(
        scene,
        scene.view(view),
        width=size,
        height=size,
        spp=spp // N_SEEDS,
        max_depth=max_depth,
        workdir=tmp_path,
    )
    s = mi.load_dict(d)
    imgs = np.stack([np.asarray(mi.render(s, seed=k), np.float64)[..., :3] for k in range(N_SEEDS)])
    return imgs.mean(0), imgs.var(0, ddof=1) / N_SEEDS


def _block(a, b=4):
    h, w, c = a.shape
    return a.reshape(h // b, b, w // b, b, c).mean(axis=(1, 3))


def _compare(cornell, tmp_path, *, size, spp, max_depth, view="front"):
    ours = render(
        cornell,
        view,
        RenderConfig(width=size, height=size, spp=spp, max_depth=max_depth, specular=0.0, progress=False),
        key=jax.random.key(11),
    )
    m_mean, m_var = _mitsuba_mean_var(
        cornell, view, size=size, spp=spp, max_depth=max_depth, tmp_path=tmp_path
    )
    o_mean = np.asarray(ours.image("full"), np.float64)
    o_var = np.asarray(ours.variance("full"), np.float64)
    # Block means: variance of a mean of 16 independent pixels = (Σ var) / 16².
    z = (_block(o_mean) - _block(m_mean)) / np.sqrt((_block(o_var) + _block(m_var)) / 16 + 1e-12)
    assert np.all(np.abs(z) < 5.5), np.abs(z).max()  # 192 tests: P(any |z| > 5.5) ~ 1e-5 under H0
    assert 0.6 < np.mean(z**2) < 1.6, np.mean(z**2)  # chi²(192)/192 lies in [0.77, 1.26] at 99.9 %
    # The whole-image mean agrees too (a bias smaller than the per-block noise would hide in z).
    tot_se = np.sqrt(o_var.sum((0, 1)) + m_var.sum((0, 1))) / size**2
    assert np.all(np.abs(o_mean.mean((0, 1)) - m_mean.mean((0, 1))) < 5 * tot_se)


def test_cornell_matches_mitsuba(cornell, tmp_path):
    _compare(cornell, tmp_path, size=32, spp=256, max_depth=6)


@pytest.mark.slow
def test_cornell_matches_mitsuba_high_spp(cornell, tmp_path):
    _compare(cornell, tmp_path, size=64, spp=2048, max_depth=8)
    _compare(cornell, tmp_path / "interior", size=64, spp=1024, max_depth=8, view="interior")
