"""Where does a run's glossy-indirect error come from? Re-runs the evaluation's steps on one finished run's
baked probes (``probeplace.evaluate``'s public steps, no patching): the glossy MSE taken apart (perfect
trace, trace share, split by ray status, resolved only), how many resolved light-field hits land at the
true distance (Embree), and the MSE with the hit / unresolved rays shaded black; with ``--by-probe K``
the K probes whose resolved hits add most to the error over the perfect trace. Prints JSON.

    PROBEPLACE_SCENE_PATH=../shared/scenes .venv/bin/python experiments/diagnose_glossy.py \\
        results/sponza_comparison/crytek_sponza__grid__b32__s0 [--width 48 --height 36 --glossy-spp 4] \\
        [--filter depth_normal|depth_aware|bilinear|texel|mip] [--by-probe 8]

The evaluation is rerun at the given (small) size with the run's view; the MSEs are therefore not the
run's, but their split is what the run's error is made of.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf


def main(argv=None) -> int:
    from probeplace.probes import DEFAULT_GLOSSY_FILTER, GLOSSY_FILTERS

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path, help="a finished run folder (with probes_baked.npz and config.yaml)")
    ap.add_argument("--width", type=int, default=48)
    ap.add_argument("--height", type=int, default=36)
    ap.add_argument("--glossy-spp", type=int, default=4)
    ap.add_argument("--filter", default=DEFAULT_GLOSSY_FILTER, choices=GLOSSY_FILTERS)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument(
        "--by-probe",
        type=int,
        default=0,
        metavar="K",
        help="also the K probes whose resolved hits add most to the light-field error over the perfect trace",
    )
    args = ap.parse_args(argv)

    from probeplace.evaluate import (
        EvalConfig,
        crn_reference,
        glossy_terms,
        perfect_trace,
        render_reference,
        sample_primary,
        score,
        shade_probes,
    )
    from probeplace.experiment import load_experiment_scene
    from probeplace.probes import glossy_maps, load_probes
    from probeplace.render import default_caster

    cfg = OmegaConf.load(args.run / "config.yaml")
    scene = load_experiment_scene(cfg.scene)
    lf = load_probes(args.run / "probes_baked.npz")
    depth = int(OmegaConf.select(cfg, "tracer.max_depth", default=8))
    config = EvalConfig(
        width=args.width,
        height=args.height,
        spp=8,
        glossy_spp=args.glossy_spp,
        max_depth=depth,
        glossy_filter=args.filter,
        timing_repeats=1,
    )
    caster = default_caster(scene)
    cam = scene.view(cfg.eval.view)
    ref = render_reference(scene, cam, config, seed=args.seed, caster=caster)
    prim = sample_primary(scene, cam, config, seed=args.seed, caster=caster)
    crn = crn_reference(scene, prim, config, seed=args.seed, caster=caster)
    maps = glossy_maps(lf, args.filter, include_emission=False)  # as the evaluation builds them
    shading = shade_probes(scene, lf, prim, config, maps=maps)
    perfect = perfect_trace(lf, prim, config, caster=caster, maps=maps)
    m = score(scene, lf, cfg.eval.view, config, args.seed, ref, prim, crn, shading, perfect).metrics

    st = shading.status
    black = lambda k: glossy_terms(
        prim.w_glossy,
        np.where((st == k)[:, None], 0.0, shading.glossy),
        crn.radiance,
        perfect.radiance,
        st,
        prim.spp,
    )["mse"]
    hit = (st == 1) & np.isfinite(perfect.t_exact)
    rel = shading.t[hit] / perfect.t_exact[hit]
    keys = (
        "mse_glossy_indirect",
        "noise_floor_glossy_indirect",
        "mse_black_glossy_indirect",
        "mse_glossy_perfect_trace",
        "mse_glossy_trace_share",
        "trace_excess",
        "mse_glossy_by_status",
        "mse_glossy_resolved_only",
        "glossy_status_share",
        "glossy_hit_agreement",
        "perfect_trace_fallback_share",
        "relmse_glossy_indirect",
        "ci95_mse_glossy_indirect",
    )
    out = {
        "run": str(args.run),
        "rays": int(np.sum(st >= 0)),
        "metrics": {k: m[k] for k in keys},
        "resolved_hits_within_5pct_of_true_distance": float(np.mean(np.abs(rel - 1) < 0.05))
        if len(rel)
        else None,
        "resolved_hits_beyond_1.5x": float(np.mean(rel > 1.5)) if len(rel) else None,
        "resolved_hits_before_0.5x": float(np.mean(rel < 0.5)) if len(rel) else None,
        "glossy_mse": {"all": m["mse_glossy_indirect"], "hits_black": black(1), "unresolved_black": black(2)},
    }
    if args.by_probe:
        out["excess_by_probe"] = _excess_by_probe(
            scene, lf, prim, crn, shading, perfect, config, args.by_probe
        )
    print(json.dumps(out, indent=1))
    return 0


def _excess_by_probe(scene, lf, prim, crn, shading, perfect, config, k: int) -> dict:
    """Each glossy ray's squared error (its own term of the pixel sum, cross terms left out) minus its
    perfect trace's, summed over the rays each probe resolved: the K probes adding most, with their
    position, rays, share of the total excess, how far their hits land from the true distance and how
    much of their excess comes from hits at the true distance (the radiance read, not the trace)."""
    import jax.numpy as jnp

    from probeplace.probes import make_tracer, trace_light_field

    gi = np.asarray(prim.glossy_idx)
    origins, directions = np.asarray(prim.origins), np.asarray(prim.directions)
    tracer = make_tracer(lf, scene.bounds, config=config.trace)
    res = trace_light_field(tracer, jnp.asarray(origins), jnp.asarray(directions))
    probe, status = np.asarray(res.probe), np.asarray(res.status)
    if not np.array_equal(status, np.asarray(shading.status)[gi]):
        raise SystemExit("the retrace disagrees with the evaluation's statuses: not the same tracer settings")
    w, ref = np.asarray(prim.w_glossy, np.float64)[gi], np.asarray(crn.radiance, np.float64)[gi]

    def sq_error(radiance):
        return np.sum((w * (np.asarray(radiance, np.float64)[gi] - ref)) ** 2, axis=-1)

    excess = sq_error(shading.glossy) - sq_error(perfect.radiance)
    hit = status == 1
    t = np.asarray(shading.t)[gi]
    rel = t / np.asarray(perfect.t_exact)[gi]
    at_truth = np.abs(rel - 1) < 0.05
    points = origins + np.where(hit, t, 0.0)[:, None] * directions
    total = float(excess.sum())
    per = {int(p): float(excess[hit & (probe == p)].sum()) for p in np.unique(probe[hit])}
    rows = []
    for p in sorted(per, key=per.get, reverse=True)[:k]:
        mine = hit & (probe == p)
        known = rel[mine][np.isfinite(rel[mine])]
        pos = np.asarray(lf.pos_world[p])
        rows.append(
            {
                "probe": p,
                "pos": [round(float(x), 2) for x in pos],
                "rays": int(mine.sum()),
                "excess_share": per[p] / total if total else None,
                "hits_within_5pct": float(np.mean(np.abs(known - 1) < 0.05)) if len(known) else None,
                "hits_short": float(np.mean(known < 0.95)) if len(known) else None,
                "hits_beyond": float(np.mean(known > 1.05)) if len(known) else None,
                "excess_share_of_hits_within_5pct": float(excess[mine & at_truth].sum()) / per[p]
                if per[p]
                else None,
                "median_hit_distance": float(np.median(t[mine])),
                "median_hit_distance_from_probe": float(
                    np.median(np.linalg.norm(points[mine] - pos, axis=-1))
                ),
            }
        )
    hit_share = float(excess[hit].sum()) / total if total else None
    return {"total_excess": total, "hit_rays_excess_share": hit_share, "probes": rows}


if __name__ == "__main__":
    raise SystemExit(main())
