"""Which unresolved rays could a light-field trace resolve at all? (issue 33's premise check)

Bakes the geometry of a uniform grid (constant radiance, as ``benchmarks/tracer.py``'s ``bake_grid``, here
with geometry maps at ``--geometry-res``), traces ``--rays`` of ``CameraMain``'s shading rays (the view's
primary hits, cosine-weighted directions: ``benchmarks/tracer.py``'s ``shading_rays``) with the default
tracer, and asks Embree, for each unresolved ray with a finite exact hit x, whether some usable probe sees
x (the segment probe → x free up to 0.1 % of its length, the probe on the side x's surface faces the ray
from), and whether one within the tracer's fallback radius of x does. A ray whose hit no usable probe
sees cannot be resolved correctly by any trace through these probes: that share of all rays is a floor
under the tracer's unresolved share.

    PROBEPLACE_SCENE_PATH=/work/shared/scenes .venv/bin/python experiments/unresolved_floor.py \\
        --grid 16x8x8 --geometry-res 512 --rays 8000

Last stdout line: one JSON object (the shares).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))


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


def _seen(caster, probe_pos, x, n, radius=None) -> np.ndarray:
    """(len(x),) whether some probe of ``probe_pos`` sees x (front side of normal n), within ``radius``."""
    out = np.zeros(len(x), bool)
    for k in range(0, len(probe_pos), 32):
        p = probe_pos[k : k + 32]
        v = x[:, None] - p[None]
        dist = np.linalg.norm(v, axis=2)
        dv = v / dist[..., None]
        origins = np.broadcast_to(p[None], v.shape).reshape(-1, 3)
        h = caster.closest_hit(jnp.asarray(origins, jnp.float32), jnp.asarray(dv.reshape(-1, 3), jnp.float32))
        t = np.where(np.asarray(h.tri) >= 0, np.asarray(h.t), np.inf).reshape(len(x), -1)
        ok = (t >= dist * (1 - 1e-3)) & (np.sum(dv * n[:, None], axis=2) < 0)
        if radius is not None:
            ok &= dist <= radius
        out |= ok.any(axis=1)
    return out


def main(argv=None) -> dict:
    from probeplace.geometry import EmbreeCaster
    from probeplace.probes import TraceConfig, TraceStatus, make_tracer, trace_light_field
    from probeplace.scene import load_scene
    from tracer import shading_rays

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="crytek_sponza")
    ap.add_argument("--grid", default="16x8x8")
    ap.add_argument("--geometry-res", type=int, default=512)
    ap.add_argument("--rays", type=int, default=8000)
    args = ap.parse_args(argv)
    scene = load_scene(args.scene)
    caster = EmbreeCaster(scene)
    o, d = shading_rays(scene, caster, args.rays, 0)
    lf = _bake(scene, tuple(int(v) for v in args.grid.split("x")), args.geometry_res, caster)
    tr = make_tracer(lf, scene.bounds, config=TraceConfig(engine="wavefront"))
    status = np.asarray(trace_light_field(tr, jnp.asarray(o), jnp.asarray(d)).status)
    h = caster.closest_hit(jnp.asarray(o), jnp.asarray(d))
    t_exact = np.where(np.asarray(h.tri) >= 0, np.asarray(h.t), np.inf)
    usable = np.asarray(lf.pos_world)[np.asarray(tr.usable)]
    radius = tr.config.fallback_radius * float(tr.spacing)
    unres = np.flatnonzero((status == TraceStatus.UNRESOLVED) & np.isfinite(t_exact))
    x = o[unres] + (t_exact[unres] - 1e-3)[:, None] * d[unres]
    n = np.asarray(h.geo_normal)[unres]
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where((np.sum(n * d[unres], axis=1) > 0)[:, None], -n, n)  # the side the ray comes from
    seen_any, seen_near = _seen(caster, usable, x, n), _seen(caster, usable, x, n, radius)
    out = {
        "scene": args.scene,
        "grid": args.grid,
        "geometry_res": args.geometry_res,
        "rays": len(o),
        "usable_probes": len(usable),
        "unresolved_share": float(np.mean(status == TraceStatus.UNRESOLVED)),
        "unresolved_hit_seen_share": float(seen_any.mean()) if len(unres) else None,
        "unresolved_hit_seen_within_radius_share": float(seen_near.mean()) if len(unres) else None,
        "unresolved_hit_unseen_of_all_rays": float(np.sum(~seen_any) / len(o)),
    }
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
