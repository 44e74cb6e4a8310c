"""Where does a run's glossy-indirect error come from? Re-traces the evaluation's glossy rays of one
finished run through its baked probes and through the exact caster (Embree), and reports how many
resolved light-field hits land at the true distance, and how much of the glossy MSE each ray status
(hit / unresolved) carries. Prints JSON.

    PROBEPLACE_SCENE_PATH=../shared/scenes .venv/bin/python experiments/diagnose_glossy.py \\
        results/sponza_comparison/crytek_sponza__grid__b32__s0 [--width 48 --height 36 --glossy-spp 4]

The evaluation is rerun at the given (small) size with the run's view; the MSEs are therefore not the
run's, but their split is what the run's error is made of.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from omegaconf import OmegaConf


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path, help="a finished run folder (with probes_baked.npz and config.yaml)")
    ap.add_argument("--width", type=int, default=48)
    ap.add_argument("--height", type=int, default=36)
    ap.add_argument("--glossy-spp", type=int, default=4)
    args = ap.parse_args(argv)

    import probeplace.evaluate._evaluate as ev
    from probeplace.evaluate import EvalConfig, evaluate
    from probeplace.experiment import load_experiment_scene
    from probeplace.probes import load_probes
    from probeplace.probes._trace import trace_light_field
    from probeplace.render import default_caster

    cfg = OmegaConf.load(args.run / "config.yaml")
    scene = load_experiment_scene(cfg.scene)
    lf = load_probes(args.run / "probes_baked.npz")
    config = EvalConfig(
        width=args.width, height=args.height, spp=8, glossy_spp=args.glossy_spp, timing_repeats=1
    )
    original = ev.glossy_radiance
    captured: dict = {}
    zero_status: list = []  # statuses whose rays are shaded black in the next evaluation

    def spy(tr, lf_, o, d, **kw):
        v, st = original(tr, lf_, o, d, **kw)
        captured.update(tracer=tr, o=o, d=d, status=st)
        for s in zero_status:
            v = jnp.where((st == s)[:, None], 0.0, v)
        return v, st

    ev.glossy_radiance = spy
    try:
        mse = {}
        for name, zero in (("all", []), ("hits_black", [1]), ("unresolved_black", [2])):
            zero_status[:] = zero
            m = evaluate(scene, lf, view=cfg.eval.view, config=config, key=jax.random.key(1)).metrics
            mse[name] = m["mse_glossy_indirect"]
        mse["black_image"] = m["mse_black_glossy_indirect"]
    finally:
        ev.glossy_radiance = original
    o, d, st = captured["o"], captured["d"], np.asarray(captured["status"])
    t_lf = np.asarray(trace_light_field(captured["tracer"], o, d).t)
    t_ex = np.asarray(default_caster(scene).closest_hit(o, d).t)
    hit = (st == 1) & np.isfinite(t_ex) & (t_ex > 0)
    rel = t_lf[hit] / t_ex[hit]
    out = {
        "run": str(args.run),
        "rays": len(st),
        "share": {
            "hit": float(np.mean(st == 1)),
            "unresolved": float(np.mean(st == 2)),
            "miss": float(np.mean(st == 0)),
        },
        "resolved_hits_within_5pct_of_true_distance": float(np.mean(np.abs(rel - 1) < 0.05)),
        "resolved_hits_beyond_1.5x": float(np.mean(rel > 1.5)),
        "resolved_hits_before_0.5x": float(np.mean(rel < 0.5)),
        "glossy_mse": mse,
    }
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
