"""How often does the light-field tracer resolve a glossy ray, and how often at the true distance?

Bakes *geometry only* (distance and normal maps; constant radiance, as ``benchmarks/tracer.py``'s
``bake_grid``) for uniform probe grids, makes the evaluation's glossy rays (the camera view's primary
hits, GGX-sampled reflection directions, offset off the surface exactly as ``evaluate`` does), traces
them through the probes and through Embree, and prints one JSON object per (grid, resolution, tracer
setting), also written to ``results/trace_accuracy/<scene>.json``.

    PROBEPLACE_SCENE_PATH=/work/shared/scenes .venv/bin/python experiments/trace_accuracy.py \\
        --scene crytek_sponza --grids 8x4x4 16x8x8 --res 32 64 --width 64 --height 36

Figures per row:

* ``unresolved``: share of rays no probe could decide;
* ``agree``: share of *resolved* rays whose answer matches Embree — both miss, or both hit with
  |t_lf − t_embree| ≤ ``rtol``·t_embree (default 2%: a surfel is exact for a plane, and 2% of the
  distance is well inside a 32² texel's footprint, ≈ 11% of the distance);
* ``agree_texel``: the same, or both hit within one geometry texel's footprint of each other, seen from
  the resolving probe (the criterion of tests/probes/test_trace.py's Cornell agreement, without its
  "near any geometry" clause);
* ``hit_early`` / ``hit_late``: share of resolved rays hitting before / after that band (or a hit
  where Embree misses: late), ``false_miss``: a miss where Embree hits;
* ``steps``: mean texel steps; ``rescued``: share of rays the last-free-point fallback probes resolved.

Bakes are cached in ``results/trace_accuracy/`` (rebaked when the cache cannot be read).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "results" / "trace_accuracy"


def glossy_rays(scene, caster, view: str, width: int, height: int, spp: int, seed: int = 0):
    """The evaluation's glossy rays (``evaluate.sample_primary``): origins off the surface, GGX directions."""
    from probeplace.evaluate import EvalConfig, sample_primary

    camera = scene.view(view) if view else scene.views[0]
    config = EvalConfig(width=width, height=height, glossy_spp=spp, progress=False)
    prim = sample_primary(scene, camera, config, seed=seed, caster=caster)
    return np.asarray(prim.origins), np.asarray(prim.directions)


def grid_probes(scene, caster, dims, res: int):
    """Geometry-only bake of a uniform grid (cell centres), cached."""
    from probeplace._core import ProbeplaceError
    from probeplace.probes import load_probes, save_probes

    sys_path = ROOT / "benchmarks"
    import sys

    if str(sys_path) not in sys.path:
        sys.path.insert(0, str(sys_path))
    from tracer import bake_grid

    path = OUT / f"{scene.name}_{'x'.join(map(str, dims))}_r{res}.npz"
    if path.exists():
        try:
            return load_probes(path), 0.0
        except ProbeplaceError as e:  # cut, corrupt or of an older layout: rebake (any other error is a bug)
            print(f"cache {path.name} unreadable ({e}); rebaking", flush=True)
    lf, bake_s = bake_grid(scene, dims, res, caster)
    OUT.mkdir(parents=True, exist_ok=True)
    save_probes(path, lf)
    return lf, bake_s


def score(out, t_ref: np.ndarray, rtol: float, texel_ok: np.ndarray | None = None) -> dict:
    from probeplace.probes import TraceStatus

    st, t = np.asarray(out.status), np.asarray(out.t, np.float64)
    ref_hit = np.isfinite(t_ref)
    resolved = st != TraceStatus.UNRESOLVED
    hit = st == TraceStatus.HIT
    close = hit & ref_hit & (np.abs(t - t_ref) <= rtol * np.where(ref_hit, t_ref, 0.0))
    agree = close | ((st == TraceStatus.MISS) & ~ref_hit)
    early = hit & ref_hit & (t < t_ref * (1 - rtol))
    late = hit & ~close & ~early
    n_res = max(int(resolved.sum()), 1)
    row = {
        "rays": len(st),
        "unresolved": float(np.mean(~resolved)),
        "agree": float(agree[resolved].sum() / n_res),
        "hit_early": float(early.sum() / n_res),
        "hit_late": float(late.sum() / n_res),
        "false_miss": float(((st == TraceStatus.MISS) & ref_hit).sum() / n_res),
        "steps": float(np.mean(np.asarray(out.steps))),
        "probes_tried": float(np.mean(np.asarray(out.probes_tried))),
    }
    if texel_ok is not None:
        row["agree_texel"] = float((texel_ok | agree)[resolved].sum() / n_res)
    if hasattr(out, "fallback"):
        fb = np.asarray(out.fallback)
        row["needed_fallback"] = float(np.mean(fb > 0))
        row["rescued"] = float(np.mean((fb > 0) & resolved))
    return row


def same_texel(out, lf, o, d, t_ref, n_ref) -> np.ndarray:
    """Per ray: a hit within one geometry texel's footprint of Embree's, seen from the resolving probe
    (the footprint of tests/probes/test_trace.py's agreement: r·√(4π)/R / max(|cos|, 0.1))."""
    st, t, p = np.asarray(out.status), np.asarray(out.t, np.float64), np.asarray(out.probe)
    hit = (st == 1) & np.isfinite(t_ref)
    pos = np.asarray(lf.pos_world, np.float64)[np.maximum(p, 0)]
    x_ref = o + np.where(np.isfinite(t_ref), t_ref, 0.0)[:, None] * d
    x_lf = o + np.where(hit, t, 0.0)[:, None] * d
    v = x_ref - pos
    r = np.linalg.norm(v, axis=1)
    cos = np.abs(np.sum(n_ref * v, axis=1)) / np.maximum(r, 1e-12)
    res = lf.distance.shape[-1] - 2
    foot = r * np.sqrt(4 * np.pi) / res / np.maximum(cos, 0.1)
    return hit & (np.linalg.norm(x_lf - x_ref, axis=1) <= foot)


def _value(item: str):
    """``key:value`` → (key, None / int / float / str)."""
    k, v = item.split(":")
    if v.lower() == "none":
        return k, None
    for cast in (int, float):
        try:
            return k, cast(v)
        except ValueError:
            pass
    return k, v


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="crytek_sponza")
    ap.add_argument("--view", default="", help="view name (default: the scene's first)")
    ap.add_argument("--grids", nargs="+", default=["8x4x4", "16x8x8"])
    ap.add_argument("--res", nargs="+", type=int, default=[32, 64])
    ap.add_argument("--width", type=int, default=64)
    ap.add_argument("--height", type=int, default=36)
    ap.add_argument("--spp", type=int, default=1)
    ap.add_argument("--rtol", type=float, default=0.02)
    ap.add_argument("--tag", default="", help="also save per-ray results as <tag>_<grid>_r<res>_<config>.npz")
    ap.add_argument(
        "--configs",
        nargs="+",
        default=["default"],
        help="TraceConfig variants as name=k:v,k:v (e.g. nofb=fallback_probes:0); 'default' is TraceConfig()",
    )
    args = ap.parse_args(argv)

    from probeplace.geometry import EmbreeCaster
    from probeplace.probes import TraceConfig, make_tracer, trace_light_field
    from probeplace.scene import load_scene

    scene = load_scene(args.scene)
    caster = EmbreeCaster(scene)
    o, d = glossy_rays(scene, caster, args.view, args.width, args.height, args.spp)
    ref = caster.closest_hit(o, d)
    t_ref = np.where(np.asarray(ref.tri) >= 0, np.asarray(ref.t, np.float64), np.inf)
    n_ref = np.asarray(ref.geo_normal, np.float64)
    configs = {}
    for spec in args.configs:
        name, _, kv = spec.partition("=")
        configs[name] = TraceConfig(**dict(_value(item) for item in filter(None, kv.split(","))))
    rows = []
    for g in args.grids:
        dims = tuple(int(x) for x in g.split("x"))
        for res in args.res:
            lf, bake_s = grid_probes(scene, caster, dims, res)
            for name, cfg in configs.items():
                tr = make_tracer(lf, scene.bounds, config=cfg)
                t0 = time.perf_counter()
                out = jax.block_until_ready(trace_light_field(tr, jnp.asarray(o), jnp.asarray(d)))
                row = {"grid": g, "res": res, "config": name, "bake_s": bake_s}
                ok = same_texel(out, lf, o.astype(np.float64), d.astype(np.float64), t_ref, n_ref)
                row |= score(out, t_ref, args.rtol, ok) | {"trace_s": time.perf_counter() - t0}
                rows.append(row)
                if args.tag:
                    np.savez(
                        OUT / f"{args.tag}_{g}_r{res}_{name}.npz",
                        status=np.asarray(out.status),
                        t=np.asarray(out.t),
                        probe=np.asarray(out.probe),
                        texel=np.asarray(out.texel),
                        steps=np.asarray(out.steps),
                        probes_tried=np.asarray(out.probes_tried),
                        fallback=np.asarray(out.fallback),
                        t_ref=t_ref,
                        o=o,
                        d=d,
                    )
                print(json.dumps(row), flush=True)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / f"{args.scene}.json").write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
