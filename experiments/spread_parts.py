"""Which count moves a fixed placement's glossy MSE between seeds, the bake's or the reference's (issue 33)

``benchmarks/convergence.py --spread-fixed-rays`` reruns a grid's seeds on seed 0's evaluation rays, so that
only the bake's and the reference's paths change between seeds; its spread mixes the two. Here the same
seeds are crossed: bake i's probes are scored against reference j's CRN radiance for every (i, j), on the
same rays (seed 0's primary samples and glossy directions; bake and reference paths of seed i and j, as the
benchmark's fixed-rays cells draw them), which costs one shading per bake and one CRN reference per seed,
the scoring n² times. From the n × n glossy MSEs:

* ``fixed_rays``: the spread of the diagonal, bake i against reference i — the benchmark's
  ``sponza_grid_seed_spread_fixed_rays``;
* ``bake``: the spread of the row means, each bake against every reference — what ``--bake-spp`` controls;
* ``reference``: the spread of the column means — what ``--glossy-ref-spp`` controls.

A spread is the benchmark's ``seed_cv`` (population σ ÷ mean) with its 95 % interval (``cv_interval``).
``--show`` prints the matrix.

    PROBEPLACE_SCENE_PATH=../shared/scenes .venv/bin/python experiments/spread_parts.py \\
        --grid 8x4x4 --seeds 5 --bake-spp 32 --glossy-ref-spp 16

Last stdout line: one JSON object.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))


def spread_parts(mse: np.ndarray) -> dict:
    """The spreads (module docstring) of an (n, n) matrix of glossy MSEs, bake seeds down the rows and
    reference seeds across the columns: each ``{"cv", "ci95"}``."""
    from convergence import cv_interval, seed_cv

    m = np.asarray(mse, np.float64)
    if m.ndim != 2 or m.shape[0] != m.shape[1] or m.shape[0] < 2:
        raise ValueError(f"want an n × n matrix of MSEs with n >= 2, got shape {m.shape}")
    parts = {"fixed_rays": np.diag(m), "bake": m.mean(axis=1), "reference": m.mean(axis=0)}
    return {k: {"cv": seed_cv(v), "ci95": cv_interval(v)} for k, v in parts.items()}


def main(argv=None) -> dict:
    import convergence as cv

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    cv.add_cell_arguments(ap, seeds=5, bake_spp=8, glossy_spp=16)
    ap.add_argument("--show", action="store_true", help="print the matrix of glossy MSEs")
    args = ap.parse_args(argv)
    if args.seeds < 2 or args.bake_spp < 1 or args.glossy_ref_spp < 2 or args.glossy_spp < 1:
        ap.error(
            "--seeds must be at least 2, --bake-spp at least 1, --glossy-ref-spp at least 2, --glossy-spp at "
            "least 1"
        )
    b, pos = cv.cell_bench_of(ap, args)

    from probeplace.evaluate import sample_errors, shade_probes
    from probeplace.probes import glossy_maps

    reads, refs = [], []
    for seed in range(args.seeds):
        t0 = time.perf_counter()
        lf, _ = b.bake(pos, args.res, seed)
        _, prim, crn, _ = b.steps(seed, ray_seed=0)  # seed 0's rays, this seed's reference paths
        maps = glossy_maps(lf, b.config.glossy_filter, include_emission=False)
        reads.append(shade_probes(b.scene, lf, prim, b.config, maps=maps).glossy)
        refs.append(crn.radiance)
        print(f"seed {seed}: baked, shaded and referenced in {time.perf_counter() - t0:.0f} s", flush=True)
    # every seed's primary samples are seed 0's (ray_seed=0): one set of weights scores them all
    mse = np.array(
        [[np.mean(sample_errors(prim.w_glossy, g, r, prim.spp)[1] ** 2) for r in refs] for g in reads]
    )
    out = {
        "grid": args.grid,
        "seeds": args.seeds,
        "bake_spp": args.bake_spp,
        "glossy_ref_spp": args.glossy_ref_spp,
        "glossy_spp": args.glossy_spp,
        "mse": mse.tolist(),
    } | spread_parts(mse)
    if args.show:
        print("glossy MSE (rows: bake seed, columns: reference seed)")
        for row in mse:
            print("  " + " ".join(f"{v:.4g}" for v in row))
    for k in ("fixed_rays", "bake", "reference"):
        lo, hi = out[k]["ci95"]
        print(f"spread {k:<11}{100 * out[k]['cv']:6.1f} %  [{100 * lo:.1f}, {100 * hi:.1f}]")
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
