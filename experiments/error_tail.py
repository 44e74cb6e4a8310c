"""The glossy error's tail and bulk, method by method (issue 33: what makes the seed spread)

Reads every run of an experiment folder written by ``experiments/run.py`` (its ``eval/images.exr``),
takes each run's per-pixel squared glossy error (``evaluate.pixel_sq_error``, what ``ci95_mse``
resamples) and splits it into its *tail*, the 1 % of pixels with the largest error
(``evaluate.top_share``, the evaluation's ``top_percent_share``), and its *bulk*, the rest. Prints, per
seed, each method's MSE, tail share, the tail's Hill index (``evaluate.tail_index``: below 2, no finite
variance over the range sampled) and how many of its tail pixels are also the baseline method's (a
sun glint no probe holds is in every method's tail; a method's own failure only in its own); then, per
method, the MSE's and the bulk's spread over seeds (coefficient of variation) and each seed's MSE and
bulk ÷ the baseline's on the same seed, with their geometric mean and 95 % t-interval
(``experiment.seed_paired_ratio``, as the report's ratios).

    .venv/bin/python experiments/error_tail.py results/sponza_v5/sponza_comparison

Last stdout line: one JSON object (per run and per method).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))


def _runs(folder: Path) -> dict[tuple[str, int], np.ndarray]:
    """(method and budget, seed) → per-pixel squared glossy error of each run folder with images (run
    folders are named ``<scene>__<method>__b<budget>__s<seed>``, experiments/run.py)."""
    from probeplace.evaluate import pixel_sq_error
    from probeplace.render import load_exr

    out = {}
    for exr in sorted(folder.glob("*/eval/images.exr")):
        _, method, budget, seed = exr.parent.parent.name.split("__")
        im = load_exr(exr)
        sq = pixel_sq_error(im["probe_glossy_indirect"], im["ref_glossy_indirect"])
        out[(f"{method} {budget}", int(seed.removeprefix("s")))] = sq
    return out


def _pct(v) -> str:
    return "—" if v is None else f"{v:.1%}"


def _num(v) -> str:
    return "—" if v is None else f"{v:.2f}"


def _ratio(q) -> str:
    """``seed_paired_ratio``'s (ratio, lo, hi) as text."""
    return "—" if q is None else f"{q[0]:.2f} [{q[1]:.2f}, {q[2]:.2f}]"


def _baseline(method: str, baseline: str) -> str:
    """The baseline method's key at the same budget as ``method``'s (``"<method> b<budget>"``)."""
    return f"{baseline} {method.split()[1]}"


def main(argv=None) -> dict:
    from convergence import seed_cv
    from probeplace.evaluate import tail_count, tail_index, top_share
    from probeplace.experiment import seed_paired_ratio

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path, help="an experiment's results folder (one sub-folder a run)")
    ap.add_argument("--baseline", default="grid", help="the method the others are divided by (same budget)")
    args = ap.parse_args(argv)
    runs = _runs(args.folder)
    if not runs:
        ap.exit(2, f"error: no run with eval/images.exr under {args.folder}: run experiments/run.py first\n")
    methods = sorted({m for m, _ in runs})
    seeds = sorted({s for _, s in runs})
    k = tail_count(next(iter(runs.values())).size)
    tail = {key: set(np.argpartition(sq, sq.size - k)[sq.size - k :]) for key, sq in runs.items()}
    fig = {}  # (method, seed) → the run's figures
    for (m, s), sq in sorted(runs.items(), key=lambda kv: (kv[0][1], kv[0][0])):
        base = tail.get((_baseline(m, args.baseline), s))
        share = top_share(sq, k)
        fig[(m, s)] = r = {
            "mse": float(sq.mean()),
            "top_percent_share": share,
            "bulk": float(sq.mean()) * (1.0 - (share or 0.0)),
            "tail_index": tail_index(sq, k),
            "tail_shared_with_baseline": None if base is None else len(base & tail[(m, s)]) / k,
        }
        shared = "—" if base is None else f"{r['tail_shared_with_baseline']:.0%}"
        print(
            f"seed {s} {m:>10}: MSE {r['mse']:.3g}, top 1 % {r['top_percent_share']:.0%} of it (tail index "
            f"{_num(r['tail_index'])}), bulk {r['bulk']:.3g}, tail pixels shared with {args.baseline}: "
            f"{shared}"
        )
    per_method = {}
    for m in methods:
        ss = [s for s in seeds if (m, s) in runs]
        b = _baseline(m, args.baseline)
        pairs = {f: [(fig[(m, s)][f], fig[(b, s)][f]) for s in ss if (b, s) in runs] for f in ("mse", "bulk")}
        per_method[m] = p = {"seeds": ss}
        for f in ("mse", "bulk"):
            p[f"{f}_cv"] = seed_cv([fig[(m, s)][f] for s in ss])
            p[f"{f}_over_baseline"] = [x / y for x, y in pairs[f]]
            # geometric mean over seeds and its 95 % t-interval in log space, as the report's ratios
            p[f"{f}_ratio_ci95"] = seed_paired_ratio(pairs[f])
        print(
            f"{m:>10}: MSE spread {_pct(p['mse_cv'])}, bulk spread {_pct(p['bulk_cv'])}; "
            f"÷ {args.baseline} by seed: "
            f"MSE {' / '.join(f'{v:.2f}' for v in p['mse_over_baseline'])}, "
            f"bulk {' / '.join(f'{v:.2f}' for v in p['bulk_over_baseline'])}; over seeds: MSE "
            f"{_ratio(p['mse_ratio_ci95'])}, bulk {_ratio(p['bulk_ratio_ci95'])}"
        )
    per_run = {f"{m}_s{s}": v for (m, s), v in fig.items()}
    out = {"folder": str(args.folder), "tail_pixels": k, "runs": per_run, "methods": per_method}
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
