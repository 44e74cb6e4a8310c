"""Which unresolved rays could a light-field trace resolve at all? (issue 33's premise check)

Bakes the geometry of a uniform grid (constant radiance, as ``benchmarks/tracer.py``'s ``bake_grid``, here
with geometry maps at ``--geometry-res``), traces ``--rays`` of ``CameraMain``'s shading rays (the view's
primary hits, cosine-weighted directions: ``benchmarks/tracer.py``'s ``shading_rays``) with the default
tracer, and asks Embree, for each unresolved ray with a finite exact hit x, whether some usable probe sees
x (the segment probe → x free up to 0.1 % of its length, the probe on the side x's surface faces the ray
from), and whether one within the tracer's fallback radius of x does. A ray whose hit no usable probe
sees cannot be resolved correctly by any trace through these probes: that share of all rays is a floor
under the tracer's unresolved share.

``--glossy`` takes instead the convergence benchmark's glossy rays (CameraMain, 64×48 pixels × 16 GGX
directions, evaluation seed ``--seed``: ``evaluate.sample_primary``), the rays of issue 33's
``sponza_16x8x8_g512_unresolved_seen``, and asks the same of the whole ray, not only its hit: a probe
certifies a stretch of ray free only where it sees it, so a ray with a point before its end (its exact
hit, or where it leaves the scene box) that no usable probe sees cannot be resolved correctly by any
light-field trace, McGuire's chain or any other. ``--points`` points a ray (midpoints of equal steps)
and the hit are tested: a gap between two points is missed, so the share is a *lower bound* of that
floor. It is reported among the rays whose origin one of the K nearest usable probes sees
(``probes.origins_seen``, the target's denominator) beside the tracer's unresolved share there.
``--margin-texels M`` asks more of a probe than exact visibility: the points before the end must be
clear of every depth edge by M geometry texels as the probe sees them (:func:`_probes_see`), the floor of
a trace that reads maps of that resolution (experiments/README.md §2, "The floor at the maps'
resolution": 2.40 % exact, 2.84 % at half a texel, 3.46 % at one, on the 16×8×8 grid at 512², 32 points
a ray; "The floor sampled finer": 2.44 % exact and 3.02 % at half a texel with 128 points, 3.10 % with 256).

    PROBEPLACE_SCENE_PATH=/work/shared/scenes .venv/bin/python experiments/unresolved_floor.py \\
        --grid 16x8x8 --geometry-res 512 --rays 8000
    PROBEPLACE_SCENE_PATH=/work/shared/scenes .venv/bin/python experiments/unresolved_floor.py \\
        --grid 16x8x8 --geometry-res 512 --glossy
    PROBEPLACE_SCENE_PATH=/work/shared/scenes .venv/bin/python experiments/unresolved_floor.py \\
        --grid 16x8x8 --geometry-res 512 --glossy --margin-texels 0.5

Last stdout line: one JSON object (the shares).
"""

from __future__ import annotations

import argparse
import json
import sys
from functools import partial
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

from probeplace.probes import TraceConfig  # noqa: E402

_THICKNESS = TraceConfig().thickness  # the tracer's surface shell, a fraction of the distance


def _bake(scene, dims, geometry_res, caster):
    from probeplace._core import ProbeSet
    from probeplace.probes import BakeConfig, bake_probes
    from tracer import grid_positions

    pos = grid_positions(scene, dims)
    probes = ProbeSet(pos_world=jnp.asarray(pos, jnp.float32), active=jnp.ones(len(pos), bool))

    def const(o, d, k):
        return jnp.full((o.shape[0], 3), 0.5, o.dtype), jnp.zeros((o.shape[0], 3), o.dtype)

    cfg = BakeConfig(
        radiance_res=4, geometry_res=geometry_res, irradiance_res=4, moments_res=4, n_sub=1, progress=False
    )
    return bake_probes(scene, probes, caster=caster, radiance_fn=const, key=jax.random.key(0), config=cfg)


def _probes_see(caster, p, x, margin: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Whether each probe at ``p`` (n, m, 3) sees its point of ``x`` (n, 3): the segment probe → x free up
    to 0.1 % of its length. Returns that (n, m) and the unit directions probe → x (n, m, 3).

    With ``margin`` (radians) > 0 the probe must also see past x's distance, less the tracer's surface
    shell (``TraceConfig.thickness``), along each of 8 directions ``margin`` around probe → x: x clears
    every depth edge by that angle. A map tells no more than that when its texels are about twice the
    margin wide: a ray's point within half a texel of an edge lies in an ambiguous march cell
    (docs/tracer.md)."""
    v = x[:, None] - p
    dist = np.linalg.norm(v, axis=2)
    dv = v / dist[..., None]
    dirs = [dv] + (_ring(dv, margin) if margin > 0 else [])
    ok = np.ones(dist.shape, bool)
    for k, w in enumerate(dirs):
        h = caster.closest_hit(
            jnp.asarray(p.reshape(-1, 3), jnp.float32), jnp.asarray(w.reshape(-1, 3), jnp.float32)
        )
        t = np.where(np.asarray(h.tri) >= 0, np.asarray(h.t), np.inf).reshape(dist.shape)
        ok &= t >= dist * (1 - (1e-3 if k == 0 else _THICKNESS))
    return ok, dv


def _ring(dv, margin: float, n: int = 8) -> list[np.ndarray]:
    """``n`` unit directions at angle ``margin`` around each of the unit directions ``dv`` (..., 3)."""
    axis = np.where((np.abs(dv[..., :1]) < 0.9), [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    a = np.cross(dv, axis)
    a /= np.linalg.norm(a, axis=-1, keepdims=True)
    b = np.cross(dv, a)
    return [
        np.cos(margin) * dv + np.sin(margin) * (np.cos(phi) * a + np.sin(phi) * b)
        for phi in 2 * np.pi * np.arange(n) / n
    ]


def _visibility(caster, probe_pos, x, n=None, margin: float = 0.0) -> np.ndarray:
    """(len(x), len(probe_pos)) whether each probe sees each point x (:func:`_probes_see`; from the front
    side of normal n, when given)."""
    out = np.zeros((len(x), len(probe_pos)), bool)
    for k in range(0, len(probe_pos), 32):
        for a in range(0, len(x), 16384):  # ≤ 0.5 M rays a cast
            xa = x[a : a + 16384]
            p = np.broadcast_to(probe_pos[None, k : k + 32], (len(xa), len(probe_pos[k : k + 32]), 3))
            ok, dv = _probes_see(caster, p, xa, margin)
            if n is not None:
                ok &= np.sum(dv * n[a : a + 16384, None], axis=2) < 0
            out[a : a + 16384, k : k + 32] = ok
    return out


def _within(probe_pos, x, radius) -> np.ndarray:
    """(len(x), len(probe_pos)) whether each probe lies within ``radius`` of each point."""
    return np.linalg.norm(x[:, None] - probe_pos[None], axis=2) <= radius


def _seen(caster, probe_pos, x, n=None, radius=None, margin: float = 0.0) -> np.ndarray:
    """(len(x),) whether some probe of ``probe_pos`` sees x (:func:`_visibility`), within ``radius``."""
    vis = _visibility(caster, probe_pos, x, n, margin)
    return (vis & _within(probe_pos, x, radius) if radius is not None else vis).any(axis=1)


def _points_seen(caster, probe_pos, x, k=16, margin: float = 0.0) -> np.ndarray:
    """:func:`_seen` for free-space points, the ``k`` probes nearest each point first (most points are
    seen by one of them), every probe only for the rest."""
    from scipy.spatial import cKDTree

    out = np.zeros(len(x), bool)
    _, idx = cKDTree(probe_pos).query(x, k=min(k, len(probe_pos)))
    for a in range(0, len(x), 32768):
        seen, _ = _probes_see(caster, probe_pos[idx[a : a + 32768]], x[a : a + 32768], margin)
        out[a : a + 32768] = seen.any(axis=1)
    rest = np.flatnonzero(~out)
    out[rest] = _seen(caster, probe_pos, x[rest], margin=margin)
    return out


def _glossy_rays(scene, caster, seed):
    """The convergence benchmark's glossy rays on Sponza (CameraMain, 64×48 × 16): origins, directions."""
    from probeplace.evaluate import EvalConfig, sample_primary

    cfg = EvalConfig(width=64, height=48, glossy_spp=16)
    prim = sample_primary(scene, scene.view("CameraMain"), cfg, seed=seed, caster=caster)
    return np.asarray(prim.origins, np.float32), np.asarray(prim.directions, np.float32)


def _box_exit(o, d, lo, hi) -> np.ndarray:
    """Ray parameter where each ray leaves the box [lo, hi] (slab test; the origins lie inside)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t_out = np.maximum((lo - o) / d, (hi - o) / d)  # each slab's exit; ±inf or nan where d is 0 on it
    return np.min(np.where(np.isfinite(t_out), t_out, np.inf), axis=1)


def _path_points(o, d, t_exact, lo, hi, n_points) -> np.ndarray:
    """(len(o), n_points, 3): midpoints of ``n_points`` equal steps to each ray's end (exact hit or where
    it leaves the box [lo, hi])."""
    t_end = np.minimum(t_exact, _box_exit(o, d, lo, hi))
    frac = (np.arange(n_points) + 0.5) / n_points
    return o[:, None] + (t_end[:, None] * frac)[..., None] * d[:, None]


def _path_floor(caster, usable, o, d, t_exact, lo, hi, n_points, margin: float = 0.0) -> np.ndarray:
    """(len(o),) whether a point of the ray before its end is seen by no usable probe
    (:func:`_path_points`; with ``margin``, clear of every depth edge by it: :func:`_probes_see`)."""
    x = _path_points(o, d, t_exact, lo, hi, n_points)
    seen = _points_seen(caster, usable, x.reshape(-1, 3), margin=margin)
    return ~seen.reshape(len(o), n_points).all(axis=1)


def _hit_points(o, d, h, rows):
    """Each ray's exact hit, 1 mm before it, and its surface normal turned toward the ray."""
    x = o[rows] + (np.asarray(h.t, np.float64)[rows] - 1e-3)[:, None] * d[rows]
    n = np.asarray(h.geo_normal)[rows]
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    return x, np.where((np.sum(n * d[rows], axis=1) > 0)[:, None], -n, n)


def _coverage(caster, usable, o, d, h, t_exact, rows, lo, hi, n_points, radius, margin: float = 0.0) -> dict:
    """For rays every tested point of which some usable probe sees: the shares a trace could certify
    (:func:`_path_points` and the hit) with the probes within ``radius`` of each point (the tracer's
    fallback radius), and as a *chain* (McGuire's: each next probe sees where the last one stopped —
    here, some probe sees both of every two consecutive points), with any usable probe or within it.
    ``margin``: as :func:`_path_floor`'s, for the points before the end."""
    x = _path_points(o[rows], d[rows], t_exact[rows], lo, hi, n_points)
    vis = _visibility(caster, usable, x.reshape(-1, 3), margin=margin).reshape(len(rows), n_points, -1)
    near = _within(usable, x.reshape(-1, 3), radius).reshape(vis.shape)
    hit = np.isfinite(t_exact[rows])
    # The end: a hit, seen from the side the ray comes from; a miss ends at the box, nothing more to see.
    end, end_near = (np.ones((len(rows), 1, len(usable)), bool) for _ in range(2))
    if hit.any():
        xh, nh = _hit_points(o, d, h, rows[hit])
        end[hit, 0], end_near[hit, 0] = _visibility(caster, usable, xh, nh), _within(usable, xh, radius)
    vis, near = np.concatenate([vis, end], axis=1), np.concatenate([near, end_near], axis=1)

    def chain(v):
        return (v[:, :-1] & v[:, 1:]).any(axis=2).all(axis=1)

    return {
        "union_within_radius": float(np.mean((vis & near).any(axis=2).all(axis=1))),
        "chain_any_probe": float(np.mean(chain(vis))),
        "chain_within_radius": float(np.mean(chain(vis & near))),
    }


def _hits_seen(caster, usable, o, d, h, rows, radius=None) -> np.ndarray:
    """Whether some usable probe (within ``radius``) sees the exact hit of each ray in ``rows``, from the
    side the ray comes from (:func:`_hit_points`)."""
    x, n = _hit_points(o, d, h, rows)
    return _seen(caster, usable, x, n, radius)


def main(argv=None) -> dict:
    from probeplace._core import scene_box
    from probeplace.evaluate import EvalConfig, hit_agreement
    from probeplace.geometry import EmbreeCaster
    from probeplace.probes import TraceConfig, TraceStatus, make_tracer, origins_seen, trace_light_field
    from probeplace.scene import load_scene
    from tracer import shading_rays

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="crytek_sponza")
    ap.add_argument("--grid", default="16x8x8")
    ap.add_argument("--geometry-res", type=int, default=512)
    ap.add_argument("--rays", type=int, default=8000, help="shading rays (without --glossy)")
    ap.add_argument(
        "--glossy", action="store_true", help="the convergence benchmark's glossy rays, whole rays"
    )
    ap.add_argument("--seed", type=int, default=0, help="their evaluation seed")
    ap.add_argument("--points", type=int, default=32, help="points tested along each ray (--glossy)")
    ap.add_argument(
        "--margin-texels",
        type=float,
        default=0.0,
        help="--glossy: a probe certifies a point before the end only if it sees past it this many geometry "
        "texels around it (0: the point itself, exact visibility)",
    )
    args = ap.parse_args(argv)
    if args.margin_texels < 0:
        ap.error(f"--margin-texels {args.margin_texels}: a margin is 0 or more texels")
    if args.margin_texels > 0 and not args.glossy:
        ap.error("--margin-texels applies to the whole rays of --glossy: add --glossy, or drop the margin")
    scene = load_scene(args.scene)
    caster = EmbreeCaster(scene)
    o, d = (
        _glossy_rays(scene, caster, args.seed) if args.glossy else shading_rays(scene, caster, args.rays, 0)
    )
    lf = _bake(scene, tuple(int(v) for v in args.grid.split("x")), args.geometry_res, caster)
    tr = make_tracer(lf, scene.bounds, config=TraceConfig(subdivide=2, engine="wavefront"))
    traced = trace_light_field(tr, jnp.asarray(o), jnp.asarray(d))
    status = np.asarray(traced.status)
    unresolved = status == TraceStatus.UNRESOLVED
    h = caster.closest_hit(jnp.asarray(o), jnp.asarray(d))
    t_exact = np.where(np.asarray(h.tri) >= 0, np.asarray(h.t), np.inf)
    usable = np.asarray(lf.pos_world)[np.asarray(tr.usable)]
    lo, hi = (np.asarray(v, np.float64) for v in scene_box(scene))
    diag = float(np.linalg.norm(hi - lo))
    radius = tr.config.fallback_radius * float(tr.spacing)
    margin = args.margin_texels * float(np.sqrt(4 * np.pi)) / args.geometry_res  # a texel's angular width
    out = {
        "scene": args.scene,
        "grid": args.grid,
        "geometry_res": args.geometry_res,
        "rays": len(o),
        "usable_probes": len(usable),
        "unresolved_share": float(np.mean(unresolved)),
    }
    agree = partial(hit_agreement, rtol=EvalConfig().agreement_rtol, atol=1e-4 * diag)
    # resolved hits within 2 % of the exact distance, as the evaluation's glossy_hit_agreement
    out["agreement"] = agree(np.asarray(traced.t), t_exact, status)[0]
    if args.glossy:  # the whole ray, among rays whose origin a probe sees (the target's denominator)
        seen = np.asarray(origins_seen(tr, jnp.asarray(o)))
        rows = np.flatnonzero(seen)
        path = _path_floor(caster, usable, o[rows], d[rows], t_exact[rows], lo, hi, args.points, margin)
        fin = np.isfinite(t_exact[rows])
        hit_unseen = np.zeros(len(rows), bool)
        hit_unseen[fin] = ~_hits_seen(caster, usable, o, d, h, rows[fin])
        floor = path | hit_unseen
        u = unresolved[rows]
        out |= {
            "seed": args.seed,
            "points_per_ray": args.points,
            "margin_texels": args.margin_texels,
            "origin_seen_rays": len(rows),
            "unresolved_seen_share": float(u.mean()),
            "floor_hit_unseen_seen_share": float(hit_unseen.mean()),
            "floor_path_unseen_seen_share": float(path.mean()),
            "floor_seen_share": float(floor.mean()),
            "unresolved_seen_above_floor_share": float(np.mean(u & ~floor)),
            "floor_rays_resolved_share": float(np.mean(floor & ~u)),
            # a floor ray's hit can still be right: its hit seen within the 0.1 % margin, or by luck
            "floor_rays_hits_agreeing": agree(
                np.asarray(traced.t)[rows[floor]], t_exact[rows[floor]], status[rows[floor]]
            )[0],
        }
        above = rows[u & ~floor]  # unresolved, though some probe sees every point tested
        cov = _coverage(caster, usable, o, d, h, t_exact, above, lo, hi, args.points, radius, margin)
        out |= {f"unresolved_above_floor_{k}": v for k, v in cov.items()}
    else:  # the exact hit of the unresolved rays
        unres = np.flatnonzero(unresolved & np.isfinite(t_exact))
        seen_any = _hits_seen(caster, usable, o, d, h, unres)
        seen_near = _hits_seen(caster, usable, o, d, h, unres, radius)
        out |= {
            "unresolved_hit_seen_share": float(seen_any.mean()) if len(unres) else None,
            "unresolved_hit_seen_within_radius_share": float(seen_near.mean()) if len(unres) else None,
            "unresolved_hit_unseen_of_all_rays": float(np.sum(~seen_any) / len(o)),
        }
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
