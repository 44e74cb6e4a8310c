"""The simple NumPy reference of the single-probe trace (``probes/tracer/_simple.py``) against exact casting,
and both light-field engines against it.

The engines share their march steps (``_march``, ``_surfels``) and probe choice (``_trace``), so comparing
them with each other (tests/probes/test_wavefront.py) cannot see a bug in a shared step; the reference
shares none of that code. Scene: the Cornell box with ONE probe (64² geometry maps), rays from free points
of the room the probe sees, in uniform directions: walls and block faces it sees (hits), the open front
(misses) and what the blocks hide from it (unknown).

**Which rays are unambiguous** ("clear") is decided by exact casting, not by the reference: from the
probe, 5×5 exact rays per texel (its centre, the bake's sample, among them) give each texel's nearest
surface and whether the texel and its 8 neighbours all see one triangle plane (``_neighbourhoods``). A
ray is clear when it meets a surface, not at a grazing angle, and every point of it up to just past that
hit either lies in front of everything the probe can have stored around its line of sight (the 3×3
texels) or looks at 3×3 texels of the hit's own plane: the reference can only pass behind that plane.

**Tolerance** (per ray, from the texel's angular size): a texel's stored distance r is the exact
distance at its centre direction; along another direction of the texel, at most δ away (δ: the largest
angle between a texel's centre and its edge, :func:`_texel_radius`), a point at distance r lies off a
plane through the stored point by r·|cos θ_c − cos θ| ≤ r·δ (θ the angle to the plane's normal). The
reference's hit lies at the stored distance of its texel, or behind it by at most ``thickness``·r; so
it is off the hit's plane by ≤ r·(δ + thickness), i.e. off the exact t by that ÷ |n·d| (n the plane's
normal, d the ray). The reference's step only decides where the crossing is bracketed: the bisection
refines it to float64 rounding. An engine's hit there is on a plane through a stored point of that
plane, tilted by its stored normal's rounding (bfloat16: < 4e-3 rad), which moves the crossing by at most
the distance to that point — two texels, ≤ 4δ·r/cos 84.5° on a plane the engine accepts
(``TraceConfig.edge_on_deg``) — × 4e-3 ÷ |n·d|: < r·δ/|n·d|, the second δ of the engines' bound. Plus
1e-4 of the scene's diagonal (0.08 mm) for float32 t (engines, caster): far above a few ulps, so the
bound holds on any instruction set.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import ProbeSet, add_border, oct_decode, oct_encode
from probeplace.geometry import BruteForceCaster
from probeplace.probes import (
    BakeConfig,
    TraceConfig,
    TraceStatus,
    bake_probes,
    make_tracer,
    trace_light_field,
)
from probeplace.probes.tracer import trace_probe_simple
from probeplace.probes.tracer._simple import _oct_encode

RES = 64  # geometry maps
SUB = 5  # exact rays per texel and axis (odd: the centre among them)
PROBE = np.array([200.0, 420.0, 200.0])  # mm: ≥ 110 mm from every surface; both blocks hide floor from it
N_RAYS = 800
THICKNESS = 0.015  # the reference's default
MIN_COS = 0.25  # clear rays meet their surface at no more than 75.5° from its normal


def _const(o, d, k):
    return jnp.full(o.shape, 0.5, o.dtype), jnp.zeros_like(o)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _texel_radius(res: int) -> float:
    """δ: the largest angle between a texel's centre direction and a point of its edge (9 points a side)."""
    c = (np.arange(res) + 0.5) * 2.0 / res - 1.0
    f = np.linspace(-1.0, 1.0, 9) / res
    one = np.full(9, 1.0 / res)
    edge = np.concatenate(
        [np.stack([f, s * one], 1) for s in (-1, 1)] + [np.stack([s * one, f], 1) for s in (-1, 1)]
    )
    vv, uu = np.meshgrid(c, c, indexing="ij")
    centre = np.stack([uu, vv], -1)
    wc = np.asarray(oct_decode(jnp.asarray(centre)))
    we = np.asarray(oct_decode(jnp.asarray(centre[:, :, None] + edge)))
    return float(np.arccos(np.clip(np.sum(wc[:, :, None] * we, -1), -1.0, 1.0)).max())


def _planes(scene):
    """Per triangle (unit normal, offset n·v0), float64, and a plane id shared by coplanar triangles."""
    tri = np.asarray(scene.vertices, np.float64)[np.asarray(scene.faces)]
    n = _unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
    off = np.sum(n * tri[:, 0], -1)
    same = (n @ n.T > 1 - 1e-9) & (np.abs(off[:, None] - off[None]) < 1e-6 * np.abs(off).max())
    return n, off, np.argmax(same, axis=1)  # id: the first coplanar triangle


def _box_exit(o, d, lo, hi):
    with np.errstate(divide="ignore"):
        return np.maximum((lo - o) / d, (hi - o) / d).min(axis=-1)


def _texels(res, x, p):
    """(row, col) of the texel of each point's direction from p (``_core.oct_encode``, not the reference)."""
    uv = np.asarray(oct_encode(jnp.asarray(_unit(x - p))))
    ij = np.clip(np.floor((uv + 1.0) * (res / 2.0)), 0, res - 1).astype(np.int64)
    return ij[..., 1], ij[..., 0]


def _neighbourhoods(caster, scene, p):
    """Per texel of the probe's map, over it and its 8 neighbours (across the octahedral fold): the nearest
    exact distance, and the plane id all their exact rays meet (-1 if not one plane)."""
    n = RES * SUB
    c = (np.arange(n) + 0.5) * 2.0 / n - 1.0
    vv, uu = np.meshgrid(c, c, indexing="ij")
    w = np.asarray(oct_decode(jnp.asarray(np.stack([uu, vv], -1)))).reshape(-1, 3)
    h = caster.closest_hit(jnp.asarray(np.broadcast_to(p, w.shape)), jnp.asarray(w))
    t = np.asarray(h.t, np.float64)
    plane = np.where(np.asarray(h.tri) >= 0, _planes(scene)[2][np.asarray(h.tri)], -1)

    def per_texel(a):
        return a.reshape(RES, SUB, RES, SUB).transpose(0, 2, 1, 3).reshape(RES, RES, SUB * SUB)

    t, plane = per_texel(t), per_texel(plane)
    one = np.where(np.all(plane == plane[..., :1], -1), plane[..., 0], -1)
    lo_b = np.asarray(add_border(jnp.asarray(t.min(-1)[..., None])))[..., 0]
    one_b = np.asarray(add_border(jnp.asarray(one[..., None])))[..., 0]
    win = [(slice(i, i + RES), slice(j, j + RES)) for i in range(3) for j in range(3)]
    lo3 = np.min([lo_b[s] for s in win], axis=0)
    plane3 = np.where(np.all([one_b[s] == one for s in win], axis=0), one, -1)
    return lo3, plane3


@pytest.fixture(scope="module")
def case(cornell):
    caster = BruteForceCaster(cornell)
    probes = ProbeSet(pos_world=jnp.asarray(PROBE[None], jnp.float32), active=jnp.ones(1, bool))
    cfg = BakeConfig(
        radiance_res=4, geometry_res=RES, irradiance_res=4, moments_res=4, n_sub=1, progress=False
    )
    lf = bake_probes(cornell, probes, caster=caster, radiance_fn=_const, key=jax.random.key(0), config=cfg)
    p = np.asarray(lf.pos_world[0], np.float64)
    lo, hi = (np.asarray(b, np.float64) for b in cornell.bounds)
    rng = np.random.default_rng(0)
    q = rng.uniform(lo + 0.02 * (hi - lo), hi - 0.02 * (hi - lo), (3 * N_RAYS, 3))
    to_q = caster.closest_hit(jnp.asarray(np.broadcast_to(p, q.shape)), jnp.asarray(_unit(q - p)))
    o = q[np.asarray(to_q.t) > np.linalg.norm(q - p, axis=1) + 1.0][:N_RAYS]  # the probe sees them (1 mm)
    d = _unit(rng.normal(size=o.shape))
    # where the tracer's trace ends (``_trace._ray_t_end``): the scene box inflated by bounds_margin
    margin = TraceConfig().bounds_margin * np.max(hi - lo)
    t_end = _box_exit(o, d, lo - margin, hi + margin)
    ref = [trace_probe_simple(lf, 0, o[i], d[i], t_end[i], thickness=THICKNESS) for i in range(len(o))]
    st_ref = np.array([s for s, _ in ref])
    t_ref = np.array([t for _, t in ref])
    hit = caster.closest_hit(jnp.asarray(o), jnp.asarray(d))
    t_ex = np.asarray(hit.t, np.float64)
    tri = np.asarray(hit.tri)
    normals, _, plane_of = _planes(cornell)
    cos = np.where(tri >= 0, np.abs(np.sum(normals[tri] * d, -1)), 0.0)
    delta = _texel_radius(RES)
    diag = float(np.linalg.norm(hi - lo))
    lo3, plane3 = _neighbourhoods(caster, cornell, p)

    def tol(t, n_delta):
        """The module docstring's bound at ray distance t: r·(n_delta·δ + thickness) / |n·d| + float32."""
        r = np.linalg.norm(o + np.where(np.isfinite(t), t, 0.0)[:, None] * d - p, axis=1)
        with np.errstate(divide="ignore"):
            return r * (n_delta * delta + THICKNESS) / cos + 1e-4 * diag

    # Clear rays (module docstring): 2048 points up to twice the tolerance past the hit (< 0.6 mm apart, a
    # tenth of a texel's width at 110 mm), each in front by more than the spacing (the radial distance moves
    # less than that to the next point) or looking at the hit's plane.
    tol_ex = tol(t_ex, 1)
    clear = (tri >= 0) & (t_ex < t_end) & (cos >= MIN_COS)
    for i in np.flatnonzero(clear):
        ts = np.linspace(0.0, t_ex[i] + 2 * tol_ex[i], 2048)
        x = o[i] + ts[:, None] * d[i]
        rows, cols = _texels(RES, x, p)
        front = np.linalg.norm(x - p, axis=1) + (ts[1] - ts[0]) < lo3[rows, cols]
        clear[i] = np.all(front | (plane3[rows, cols] == plane_of[tri[i]]))
    return dict(
        lf=lf, o=o, d=d, t_end=t_end, st_ref=st_ref, t_ref=t_ref, t_ex=t_ex, clear=clear, tol=tol, p=p,
        caster=caster, scene=cornell,
    )  # fmt: skip


@pytest.fixture(scope="module", params=["per_ray", "wavefront"])
def engine(request, case):
    """(engine name, status, t) of the rays traced through the one probe by each engine. No fallback search:
    with one probe it has none to find (the same answers, measured), and it is half the compile time."""
    cfg = TraceConfig(engine=request.param, fallback_probes=0)
    tr = make_tracer(case["lf"], case["scene"].bounds, config=cfg)
    o, d = (jnp.asarray(case[k], jnp.float32) for k in ("o", "d"))
    out = trace_light_field(tr, o, d, jnp.asarray(case["t_end"], jnp.float32))
    return request.param, np.asarray(out.status), np.asarray(out.t, np.float64)


def test_reference_octahedral_map_is_the_core_one():
    """The reference's NumPy copy of the octahedral mapping is ``_core.oct_encode``'s."""
    w = _unit(np.random.default_rng(3).normal(size=(2000, 3)))
    np.testing.assert_allclose(_oct_encode(w), np.asarray(oct_encode(jnp.asarray(w))), rtol=0, atol=1e-12)


def test_reference_matches_exact_casting(case):
    """Where the probe sees the way to the hit unambiguously (clear rays), the reference never misses and
    its hits are the exact hit within the texel bound; on a plane seen obliquely a crossing at a jump of
    the stored distance between two texels exceeds the thickness — unknown, the only other answer."""
    clear, st, t = case["clear"], case["st_ref"], case["t_ref"]
    assert clear.sum() >= 100, clear.sum()
    assert np.all(st[clear] != TraceStatus.MISS)
    hit = clear & (st == TraceStatus.HIT)
    assert hit.sum() >= 0.8 * clear.sum(), (hit.sum(), clear.sum())  # measured: 152 of 170
    err = np.abs(t - case["t_ex"])
    assert np.all(err[hit] <= case["tol"](t, 1)[hit]), np.max((err / case["tol"](t, 1))[hit])


def test_engines_agree_with_the_reference_where_both_hit(case, engine):
    """Clear rays the reference hits: no engine misses one, and where an engine hits too it is at the
    reference's t within the sum of the two models' bounds (module docstring). Most are engine hits (147
    of 152 measured; the others: ``test_engines_hit_every_clear_reference_hit``)."""
    name, st, t = engine
    hit = case["clear"] & (case["st_ref"] == TraceStatus.HIT)
    assert not np.any(hit & (st == TraceStatus.MISS)), name
    both = hit & (st == TraceStatus.HIT)
    assert both.sum() >= 0.9 * hit.sum(), (name, both.sum(), hit.sum())
    err = np.abs(t - case["t_ref"])
    tol = case["tol"](case["t_ref"], 2)
    assert np.all(err[both] <= tol[both]), (name, np.max((err / tol)[both]))


def test_engines_hit_every_clear_reference_hit(case, engine):
    """Every clear ray the reference hits is an engine hit. Until the concave-crease partners left out a
    neighbour within the shell's angle (``_march._partners``), 5 of the 152 failed here: neighbours on one
    flat wall were each other's partners, and their planes, tilted apart by the bfloat16 normals (3e-3 rad),
    met the ray 0.05–0.13 mm apart, which left rays reaching the wall near their origin unknown (e.g.
    o = (542.96, 355.61, 259.09), d = (0.9849, 0.0001, −0.1730): the red wall at t ≈ 12.1)."""
    name, st, _ = engine
    hit = case["clear"] & (case["st_ref"] == TraceStatus.HIT)
    bad = hit & (st != TraceStatus.HIT)
    assert not bad.any(), f"{name}: {bad.sum()} of {hit.sum()} not hits, e.g. rays {np.flatnonzero(bad)[:5]}"


def _off_surface(case, st, t):
    """Engine hits not at the exact hit (within the bound for an engine hit, module docstring), or where
    exact casting finds no surface."""
    with np.errstate(invalid="ignore"):  # inf − inf where neither hits: not compared
        off = ~(np.abs(t - case["t_ex"]) <= case["tol"](t, 2))
    return (st == TraceStatus.HIT) & off


def test_engines_make_no_hit_where_the_probe_cannot_see(case, engine):
    """Rays the reference calls unknown and whose exact hit the probe cannot see (it lies behind a block
    from the probe), and rays that meet no surface at all: with the one probe, an engine may leave them
    unresolved or hit the surface exact casting finds, never another one."""
    name, st, t = engine
    unknown = case["st_ref"] == TraceStatus.UNKNOWN
    hidden = _hidden_hits(case)
    assert (unknown & hidden).sum() >= 30, (unknown & hidden).sum()
    rays = (unknown & hidden) | ~np.isfinite(case["t_ex"])
    wrong = rays & _off_surface(case, st, t)
    assert not wrong.any(), f"{name}: hits off the exact surface: rays {np.flatnonzero(wrong)[:5]}"


@pytest.mark.xfail(
    strict=True,
    reason="engine defect (found by this test): a silhouette taken for a concave crease "
    "(_surfels._pair: the tall block's side face and the back wall behind it pass the crease test) leaves "
    "the cell one-surface, so a ray passing just beside the block crosses the face's plane extended past "
    "the block's edge and both engines call it a hit in free space: o=(154.26, 124.49, 466.59), "
    "d=(0.7463, 0.6625, 0.0641): hit at t = 224.28 (26 mm beyond the block's back edge, 95 mm in front of "
    "the back wall seen from the probe); exact casting hits the red wall at t = 537.70; the reference says "
    "unknown at t = 222.27. The edge-on rule (84.5°) lets it through: at 64² it allows 40 % off the "
    "surfel's distance, here 26 %",
)
def test_engines_make_no_hit_beside_a_silhouette(case, engine):
    """Every ray the reference calls unknown, also those passing beside a silhouette (within its texel, so
    the probe cannot tell) on to a surface it sees: an engine hit must be the exact one."""
    name, st, t = engine
    wrong = (case["st_ref"] == TraceStatus.UNKNOWN) & _off_surface(case, st, t)
    assert not wrong.any(), f"{name}: hits off the exact surface: rays {np.flatnonzero(wrong)[:5]}"


def _hidden_hits(case):
    """Rays whose exact hit exists and lies behind something else seen from the probe (by 1 mm)."""
    o, d, t_ex, p = case["o"], case["d"], case["t_ex"], case["p"]
    x = o + np.where(np.isfinite(t_ex), t_ex, 0.0)[:, None] * d
    r = np.linalg.norm(x - p, axis=1)
    seen = case["caster"].closest_hit(jnp.asarray(np.broadcast_to(p, x.shape)), jnp.asarray(_unit(x - p)))
    return np.isfinite(t_ex) & (np.asarray(seen.t) < r - 1.0)
