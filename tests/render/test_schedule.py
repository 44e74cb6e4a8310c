"""Bounce schedules (PERF): live-lane compaction renders what the fused loop renders, on every caster.

All schedules draw the same random numbers per (pixel, sample, bounce), so the oracle is the fused
``while_loop`` over every lane (the original design): images agree up to float round-off."""

import jax
import numpy as np
import pytest

from probeplace.render import RenderConfig, render


def _render(scene, schedule, caster=None, **kw):
    cfg = RenderConfig(
        width=16, height=16, spp=8, max_depth=6, rr_depth=3, progress=False, schedule=schedule, **kw
    )
    res = render(scene, "front", cfg, key=jax.random.key(3), caster=caster)
    return np.asarray(res.mean, np.float64), np.asarray(res.var_of_mean, np.float64)


def test_compact_matches_fused(cornell):
    # small batches: several blocks and several batches per render
    m_c, v_c = _render(cornell, "compact", paths_per_batch=1024)
    m_f, v_f = _render(cornell, "fused", paths_per_batch=1024)
    assert m_c.max() > 0
    np.testing.assert_allclose(m_c, m_f, rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(v_c, v_f, rtol=1e-3, atol=1e-8)


@pytest.mark.slow
def test_host_caster_compaction_matches_jitted(cornell):
    pytest.importorskip("embreex")
    from probeplace.geometry import make_caster

    m_h, _ = _render(cornell, "compact", caster=make_caster(cornell, "embree"))
    m_j, _ = _render(cornell, "compact")
    # Embree and the brute-force caster differ in the last bits of t: a path may rarely take another
    # turn, so compare per pixel loosely and the image mean tightly
    close = np.isclose(m_h, m_j, rtol=1e-3, atol=1e-5)
    assert close.mean() > 0.98
    assert m_h[-1].mean() == pytest.approx(m_j[-1].mean(), rel=2e-2)


def test_bad_schedule():
    from probeplace._core import ConfigError

    with pytest.raises(ConfigError):
        RenderConfig(width=4, height=4, spp=1, schedule="nope")
