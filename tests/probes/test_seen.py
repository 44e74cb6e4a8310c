"""``probes.origins_seen``: whether one of the K nearest usable probes sees a point, by the tracer's own test.

Oracle: the exact caster on the Cornell box (3×3×3 grid, 64² geometry maps).

* A free point the exact caster shows a usable probe of its pool (``tr.near.lookup``) unoccluded, with
  every surface that probe sees within a few texels of the point's direction beyond it and its plane
  behind the point (by a margin of its distance: well away from edges and surfaces at the texels'
  footprint), is seen.
* A point deep inside one of the two closed convex blocks is in front of no surface any outside probe
  sees (every face's outward plane has it behind), so it is not seen — with probes in its pool.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace.geometry import BruteForceCaster
from probeplace.probes import BakeConfig, bake_probes, make_tracer, origins_seen
from probeplace.scene import load_scene
from probeplace.scene.builtin._cornell import _PARTS
from tests.helpers import grid_probe_set

GEO = 64  # geometry maps' resolution
TEXEL = float(np.sqrt(4 * np.pi)) / GEO  # a texel's angular width (4π sr over GEO² texels)
# The oracle's margin, a fraction of the distance: far above the surfels' bfloat16 normals' tilt (< 4e-3
# rad) and float32 rounding, so no case is near the test's threshold.
MARGIN = 0.05


def _const(o, d, k):
    return jnp.full(o.shape, 0.5, o.dtype), jnp.zeros_like(o)


@pytest.fixture(scope="module")
def cornell():
    scene = load_scene("cornell_box")
    caster = BruteForceCaster(scene)
    cfg = BakeConfig(
        radiance_res=4, geometry_res=GEO, irradiance_res=4, moments_res=4, n_sub=1, progress=False
    )
    probes = grid_probe_set(scene, (3, 3, 3))
    lf = bake_probes(scene, probes, caster=caster, radiance_fn=_const, key=jax.random.key(0), config=cfg)
    return scene, caster, lf, make_tracer(lf, scene.bounds)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _cone(w: np.ndarray) -> np.ndarray:
    """(m, 3) unit directions → (m, 17, 3): each and 16 around it, 1.25 and 2.5 texels away."""
    a = np.where(np.abs(w[:, :1]) > 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    u = _unit(np.cross(w, a))
    v = np.cross(w, u)
    out = [w]
    for ang in (1.25 * TEXEL, 2.5 * TEXEL):
        for phi in np.arange(8) * np.pi / 4:
            off = np.cos(phi) * u + np.sin(phi) * v
            out.append(_unit(w + np.tan(ang) * off))
    return np.stack(out, axis=1)


def _clearly_sees(caster, probe_pos: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Per (probe, point) pair: the exact caster shows the point unoccluded from the probe, every surface
    the probe sees within 2.5 texels of the point's direction is beyond it, and the point lies in front
    of each such surface's plane (on the probe's side), all by ``MARGIN`` of the distance."""
    rel = x - probe_pos
    d = np.linalg.norm(rel, axis=-1)
    dirs = _cone(rel / d[:, None])  # (m, c, 3)
    m, c = dirs.shape[:2]
    o = np.repeat(probe_pos, c, axis=0)
    h = caster.closest_hit(jnp.asarray(o, jnp.float32), jnp.asarray(dirs.reshape(-1, 3), jnp.float32))
    hit = np.asarray(h.tri).reshape(m, c) >= 0
    t = np.where(hit, np.asarray(h.t, np.float64).reshape(m, c), np.inf)
    n = np.asarray(h.geo_normal, np.float64).reshape(m, c, 3)
    n = np.where((np.sum(n * dirs, -1) > 0)[..., None], -n, n)  # turned toward the probe
    s = probe_pos[:, None] + np.where(hit, t, 0.0)[..., None] * dirs
    front = np.sum((x[:, None] - s) * n, -1) > MARGIN * np.where(hit, t, 0.0)
    return np.all(t > (1 + MARGIN) * d[:, None], axis=1) & np.all(~hit | front, axis=1)


def _pools(tr, pts: np.ndarray) -> np.ndarray:
    pool, _ = jax.vmap(tr.near.lookup)(jnp.asarray(pts, jnp.float32))
    return np.asarray(pool)


def test_points_a_probe_clearly_sees_are_seen(cornell):
    scene, caster, lf, tr = cornell
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    rng = np.random.default_rng(0)
    pts = lo + rng.uniform(0.02, 0.98, (300, 3)) * (hi - lo)
    pool = _pools(tr, pts)
    i, j = np.nonzero(pool >= 0)
    ok = _clearly_sees(caster, np.asarray(lf.pos_world, np.float64)[pool[i, j]], pts[i])
    positive = np.zeros(len(pts), bool)
    positive[i[ok]] = True
    assert positive.sum() >= 100  # the oracle decides for a good share of the points
    seen = np.asarray(origins_seen(tr, jnp.asarray(pts, jnp.float32)))
    assert seen.dtype == bool and seen.shape == (len(pts),)
    assert seen[positive].all(), pts[positive & ~seen]


def _inside_block(name: str, rng, n: int) -> np.ndarray:
    """Points deep inside a Cornell block (mm; convex): its corners' centroid + 0.5 × (random corner mix −
    centroid)."""
    corners = np.unique(np.asarray(_PARTS[name], np.float64).reshape(-1, 3), axis=0)
    centre = corners.mean(axis=0)
    w = rng.dirichlet(np.ones(len(corners)), n)
    return centre + 0.5 * (w @ corners - centre)


def test_points_inside_the_blocks_are_not_seen(cornell):
    _, _, _, tr = cornell
    rng = np.random.default_rng(1)
    pts = np.concatenate([_inside_block(b, rng, 60) for b in ("short_block", "tall_block")])
    pool = _pools(tr, pts)
    assert ((pool >= 0) & np.asarray(tr.usable)[np.maximum(pool, 0)]).any(axis=1).all()  # probes to ask
    assert not np.asarray(origins_seen(tr, jnp.asarray(pts, jnp.float32))).any()


def test_origins_seen_chunks_and_empty(cornell):
    scene, _, _, tr = cornell
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    pts = jnp.asarray(lo + np.random.default_rng(2).uniform(0, 1, (50, 3)) * (hi - lo), jnp.float32)
    np.testing.assert_array_equal(
        np.asarray(origins_seen(tr, pts, chunk=7)), np.asarray(origins_seen(tr, pts))
    )
    assert origins_seen(tr, jnp.zeros((0, 3), jnp.float32)).shape == (0,)
