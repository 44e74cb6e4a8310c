"""Light leaking through the thin wall of the ``rooms`` scene into the sealed dark room D (issue 4).

Oracle: D is sealed, so the true irradiance on its surfaces is exactly zero; whatever a probe method
puts there is leaked. The probes are baked with a radiance field that is 1 on every surface outside D
and 0 inside it (the scene's lighting pattern with the light spread over every lit surface, so the
test is cheap and has no path-tracing noise); a uniform 7×2×5 grid has cages that straddle the thin
wall. Chebyshev visibility (McGuire 2017 §5.2) must leak at most a tenth of what visibility-free
irradiance probes (Luo 2022) leak.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import ProbeSet
from probeplace.geometry import make_caster
from probeplace.probes import BakeConfig, bake_probes, diffuse_irradiance, sh_irradiance
from probeplace.scene import ROOMS_DARK_ROOM_BOUNDS, ROOMS_LIT_ROOM_BOUNDS, load_scene


@pytest.fixture(scope="module")
def rooms_lf():
    scene = load_scene("rooms")
    caster = make_caster(scene)
    xs, ys, zs = 0.5 + 2.0 * np.arange(7), np.array([0.75, 2.25]), 0.5 + 2.0 * np.arange(5)
    pos = np.stack(np.meshgrid(xs, ys, zs, indexing="ij"), -1).reshape(-1, 3)
    probes = ProbeSet(pos_world=jnp.asarray(pos, jnp.float32), active=jnp.ones(len(pos), bool))
    x_dark = ROOMS_DARK_ROOM_BOUNDS[1][0]

    def lit_outside_dark_room(o, d, k):
        h = caster.closest_hit(o, d)
        x = o + jnp.where(h.tri >= 0, h.t, 0.0)[:, None] * d
        lit = (h.tri >= 0) & (x[:, 0] > x_dark + 0.01)
        return jnp.where(lit[:, None], 1.0, 0.0) * jnp.ones_like(o), jnp.zeros_like(o)

    cfg = BakeConfig(radiance_res=16, n_sub=1, probes_per_batch=len(pos), progress=False)
    lf = bake_probes(
        scene, probes, caster=caster, radiance_fn=lit_outside_dark_room, key=jax.random.key(0), config=cfg
    )
    return scene, lf


def _dark_room_receivers(m=300, seed=0):
    """Points on D's floor, ceiling and the D face of the thin wall, within 1.4 m of the wall."""
    rng = np.random.default_rng(seed)
    x_wall = ROOMS_DARK_ROOM_BOUNDS[1][0]
    h = ROOMS_DARK_ROOM_BOUNDS[1][1]
    u = lambda a, b: rng.uniform(a, b, m)
    floor = np.stack([u(2.6, x_wall - 0.02), np.zeros(m), u(0.2, 8.8)], 1)
    ceil = np.stack([u(2.6, x_wall - 0.02), np.full(m, h), u(0.2, 8.8)], 1)
    wall = np.stack([np.full(m, x_wall), u(0.2, h - 0.2), u(0.2, 8.8)], 1)
    nrm = np.concatenate(
        [np.tile([0.0, 1, 0], (m, 1)), np.tile([0.0, -1, 0], (m, 1)), np.tile([-1.0, 0, 0], (m, 1))]
    )
    return jnp.asarray(np.concatenate([floor, ceil, wall]), jnp.float32), jnp.asarray(nrm, jnp.float32)


def test_chebyshev_visibility_cuts_light_leak_tenfold(rooms_lf):
    _, lf = rooms_lf
    x, n = _dark_room_receivers()
    leak_vis = float(jnp.mean(diffuse_irradiance(lf, x, n, visibility=True)))
    leak_plain = float(jnp.mean(diffuse_irradiance(lf, x, n, visibility=False)))
    leak_sh = float(jnp.mean(sh_irradiance(lf, x, n)))
    assert leak_plain > 0.1  # the baseline does leak (the wall sits inside the probe cages)
    assert leak_sh > 0.1
    assert leak_vis <= 0.1 * leak_plain


def test_lit_room_is_not_darkened_by_visibility(rooms_lf):
    """Away from walls the visibility weights must not lose light: in the lit room A (every surface
    radiates 1, the sky is black) the floor's irradiance is ≈ π·1 minus the few dark directions."""
    _, lf = rooms_lf
    rng = np.random.default_rng(1)
    (x0, _, z0), (x1, _, z1) = ROOMS_LIT_ROOM_BOUNDS
    m = 200
    x = np.stack([rng.uniform(x0 + 0.3, x1 - 0.3, m), np.zeros(m), rng.uniform(z0 + 0.3, z1 - 0.3, m)], 1)
    n = np.tile([0.0, 1.0, 0.0], (m, 1))
    e = np.asarray(diffuse_irradiance(lf, jnp.asarray(x, jnp.float32), jnp.asarray(n, jnp.float32)))
    # Seen from A's floor every direction ends on a lit surface (or a doorway into lit B/C): E = π. The
    # bake's cosine quadrature and texels straddling the dark wall's edge cost a few percent.
    np.testing.assert_allclose(e.mean(), np.pi, rtol=0.05)


def test_light_leak_flags_injected_leaks_not_reference_noise():
    """The metric on a synthetic reference with known per-pixel noise: probe = the reference's true
    value + Gaussian noise of up to 2 standard errors everywhere (never flagged at k = 4), plus injected
    leaks of 10 standard errors on a known set of pixels (each flagged). Pixels whose reference variance
    is 0 (all paths returned the same value: standard error unknown) are never judged, however bright
    the probe is there; non-hit pixels neither."""
    from probeplace.evaluate._decompose import LEAK_SIGMAS, light_leak

    rng = np.random.default_rng(0)
    h, w = 40, 50
    ref = rng.uniform(0.1, 1.0, (h, w, 3))
    se = rng.uniform(0.01, 0.05, (h, w))  # per-pixel standard error, the same in every channel
    var = np.repeat((se**2)[..., None], 3, axis=-1)
    lum_se = se  # Σ_c a_c σ_c with equal σ_c: the Rec. 709 weights sum to 1
    z = np.clip(rng.normal(0.0, 1.0, (h, w)), -2.0, 2.0)  # noise-level differences, |z| ≤ 2 < k
    probe = ref + (z * lum_se)[..., None]
    leak_px = rng.random((h, w)) < 0.05
    probe[leak_px] += 10.0 * lum_se[leak_px][:, None]
    unknown = rng.random((h, w)) < 0.2  # zero-variance reference pixels: standard error unknown
    var[unknown] = 0.0
    probe[unknown] += 100.0
    judge = np.ones((h, w), bool)
    judge[:, :3] = False  # pixels with no primary hit
    probe[:, :3] += 100.0

    out = light_leak(ref, var, probe, judge)
    assert LEAK_SIGMAS == 4.0
    np.testing.assert_array_equal(out["judged"], judge & ~unknown)
    np.testing.assert_array_equal(out["flagged"], leak_px & judge & ~unknown)
    want = float(np.sum(np.where(out["flagged"], ((probe - ref) @ [0.2126, 0.7152, 0.0722]), 0.0)))
    assert out["energy"] == pytest.approx(want / (h * w), rel=1e-12)  # float64 sums of the same terms
    # the same image with no leak: nothing flagged, whatever the noise
    clean = light_leak(ref, var, ref + (z * lum_se)[..., None], judge)
    assert not clean["flagged"].any() and clean["energy"] == 0.0
