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
