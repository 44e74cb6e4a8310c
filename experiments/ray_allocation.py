"""Where a pixel's glossy rays should go: a fixed placement's seed spread against the rays spent (issue 33)

A Sponza grid's glossy MSE moves between seeds mostly by which surfaces a pixel's rays happen to reach, and
a few dozen pixels hold most of that (experiments/README.md §2). This reruns one cell of
``benchmarks/convergence.py`` on seeds 0 … N − 1 (each seed its own bake, rays and reference, as the
benchmark's ``sponza_grid_seed_spread``), keeps every glossy ray's error x = w (L_probe − L_ref) and the
black image's −w L_ref, and spends those rays three ways:

* ``uniform`` k: the first k of each pixel's S rays (k = S/8 … S); the spread of the plain glossy MSE and of
  the converged one (``evaluate.converged_sq_error``, unbiased for infinitely many rays and paths);
* ``allocated`` B: pixel i keeps its first n_i rays, Σ n_i ≤ B × pixels, n_i = clip(λ s_i, 2, S)
  (:func:`allocate`), s_i a pilot's score of pixel i taken from **another** seed's run (seed j + 1 mod N:
  its own rays, bake and reference, so the pilot shares no sample with the estimate and the converged MSE
  stays unbiased). Scores: ``error``, σ_i (σ_i + |μ_i|) of the pilot's errors (a rough Neyman allocation
  for the converged estimate's per-pixel variance 4μ²σ²/n + 2σ⁴/n²), and ``black``, σ_i of the pilot's
  black image (the reference's own scatter, the same for every placement). Only the converged MSE is
  reported here: the plain one's sampling noise Σ σ_i² / n_i depends on the allocation, so plain MSEs of
  two allocations do not compare.
* ``split`` m: the error split at the glossy ray's hit into the part a probe could carry, D = w (L_probe −
  L_diffuse), and the view-dependent part no probe stores, G = w (L_ref − L_diffuse) (the reference's
  specular lobe at the hit: sun glints; ``CrnReference.diffuse_at_hit``), the same for every placement.
  A pixel's converged error (D̄ − Ḡ)² − Var(D̄) − Var(Ḡ), D from the seed's own rays and G's mean from the
  rays of m other seeds (:func:`split_converged`): what a shared, many-ray estimate of the view-dependent
  part would buy.

The data cap n_i at S (64 by default; at B = S/2 the hardest pixels are already at it). A larger
``--glossy-spp`` lifts the cap but also narrows every ray's read cone, 1/(S pdf) (``probes._glossy``), so
the first k of S rays score a sharper read than a k-ray run would. A spread is the benchmark's ``seed_cv``
with its 95 % interval (``cv_interval``) and each seed's figure; ten seeds give about ×0.7–1.9.

    PROBEPLACE_SCENE_PATH=../shared/scenes .venv/bin/python experiments/ray_allocation.py \\
        --grid 8x4x4 --seeds 10 --glossy-spp 64 --glossy-ref-spp 4 --bake-spp 32

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

#: The fewest rays a pixel keeps: the converged estimate needs two (a pair of different rays).
MIN_RAYS = 2
SCORES = ("error", "black")


def per_ray(w, est, ref, spp: int) -> np.ndarray:
    """(pixels, ``spp``, 3) each ray's w (est − ref): ``evaluate.sample_errors``' parts without their 1/S."""
    from probeplace.evaluate import sample_errors

    return sample_errors(w, est, ref, spp)[0].reshape(-1, spp, 3) * spp


def converged_mse_of_counts(x: np.ndarray, n: np.ndarray) -> float:
    """The converged glossy MSE from the first ``n[i]`` rays of pixel i: ``evaluate.converged_sq_error`` (per
    pixel the mean over ordered pairs of different rays of x_s x_t) of each group of pixels that keep the
    same count, averaged over all pixels.

    Args:
        x: (pixels, S, 3) each ray's error w (L_probe − L_ref).
        n: (pixels,) rays each pixel keeps, 2 … S.
    """
    from probeplace.evaluate import converged_sq_error

    x = np.asarray(x, np.float64)
    n = np.asarray(n)
    if n.shape != x.shape[:1] or n.min() < MIN_RAYS or n.max() > x.shape[1]:
        raise ValueError(f"want one count in [{MIN_RAYS}, {x.shape[1]}] a pixel for {x.shape[0]} pixels")
    total = 0.0
    for k in np.unique(n):
        e_s = x[n == k, :k].reshape(-1, 3) / k  # sample_errors' parts, w (L − L_ref) / S with S = k
        total += float(np.sum(converged_sq_error(e_s, e_s.reshape(-1, k, 3).sum(axis=1))))
    return total / len(n)


def allocate(score: np.ndarray, budget: float, cap: int) -> np.ndarray:
    """Rays a pixel, n_i = clip(λ s_i, 2, cap) rounded to whole rays with Σ n_i ≤ ``budget`` × pixels (λ by
    bisection, the rays rounding down leaves given to the largest remainders): a pixel gets rays in
    proportion to its ``score`` between the floor and the cap. Raises ValueError for a budget outside
    [2, cap]."""
    s = np.maximum(np.asarray(score, np.float64), 0.0)
    if not MIN_RAYS <= budget <= cap:
        raise ValueError(f"the budget {budget:g} rays a pixel is outside [{MIN_RAYS}, {cap}]")
    total = budget * len(s)
    counts = lambda lam: np.floor(np.clip(lam * s, MIN_RAYS, cap))
    hi = cap / s[s > 0].min() if (s > 0).any() else 0.0  # at hi every pixel with a score is at the cap
    if counts(hi).sum() <= total:
        return counts(hi).astype(int)
    lo = 0.0  # every pixel at the floor: within the budget, which is at least the floor
    while hi - lo > 1e-9 * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if counts(mid).sum() <= total else (lo, mid)
    n = counts(lo)
    # the rays rounding down left: one more each to the pixels below the cap with the largest remainder
    remainder = np.where(n < cap, np.clip(lo * s, MIN_RAYS, cap) - n, -1.0)
    n[np.argsort(-remainder, kind="stable")[: int(total - n.sum())]] += 1
    return n.astype(int)


def pilot_score(x: np.ndarray, kind: str) -> np.ndarray:
    """Each pixel's score (module docstring) from a pilot's (pixels, S, 3) per-ray values: its errors for
    ``"error"``, its black image's for ``"black"``; σ and μ over the rays, averaged over channels."""
    x = np.asarray(x, np.float64)
    sigma = np.sqrt(x.var(axis=1, ddof=1).mean(axis=1))
    if kind == "black":
        return sigma
    if kind == "error":
        return sigma * (sigma + np.abs(x.mean(axis=1)).mean(axis=1))
    raise ValueError(f"unknown score {kind!r}; choose from {SCORES}")


def split_converged(x: np.ndarray, g_own: np.ndarray, g_pool: np.ndarray) -> float:
    """The converged glossy MSE with the view-dependent part's pixel means taken from other rays (module
    docstring, ``split``): mean over pixels and channels of (D̄ − Ḡ)² − s_D² / S − s_G² / P, with
    D = x + g_own the rays' error against the diffuse lobe and Ḡ, s_G² the mean and sample variance of the
    pool's P rays a pixel (independent of x's). With no view dependence (G ≡ 0) it is
    :func:`converged_mse_of_counts` of all S rays.

    Args:
        x: (pixels, S, 3) each ray's error w (L_probe − L_ref).
        g_own: (pixels, S, 3) the same rays' w (L_ref − L_diffuse).
        g_pool: (pixels, P, 3) w (L_ref − L_diffuse) of other rays, P >= 2.
    """
    d = np.asarray(x, np.float64) + np.asarray(g_own, np.float64)
    g = np.asarray(g_pool, np.float64)
    mean_var = lambda v: (v.mean(axis=1), v.var(axis=1, ddof=1) / v.shape[1])
    (md, vd), (mg, vg) = mean_var(d), mean_var(g)
    return float(np.mean((md - mg) ** 2 - vd - vg))


def spreads(errors: list[np.ndarray], blacks: list[np.ndarray], budgets, views=None) -> dict:
    """Every spread of the module docstring from each seed's (pixels, S, 3) ray errors and black values
    and, for ``split``, view-dependent parts ``views`` (None: no ``split`` rows)."""
    from convergence import cv_interval, seed_cv

    n_px, S = errors[0].shape[:2]
    spread = lambda v: {
        "cv": seed_cv(v),
        "ci95": cv_interval(v),
        "mean": float(np.mean(v)),
        "values": list(v),
    }
    out = {"uniform": {}, "allocated": {k: {} for k in SCORES}}
    for k in sorted({S // 8, S // 4, S // 2, S, *budgets} - {0, 1}):
        n = np.full(n_px, k)
        plain = [float(np.mean(x[:, :k].mean(axis=1) ** 2)) for x in errors]
        out["uniform"][k] = {
            "plain": spread(plain),
            "converged": spread([converged_mse_of_counts(x, n) for x in errors]),
        }
    for kind in SCORES:
        pilots = errors if kind == "error" else blacks
        scores = [pilot_score(p, kind) for p in pilots]  # seed j's pilot is seed j + 1's run
        for budget in budgets:
            values = [
                converged_mse_of_counts(x, allocate(scores[(j + 1) % len(errors)], budget, S))
                for j, x in enumerate(errors)
            ]
            out["allocated"][kind][budget] = {"converged": spread(values)}
    if views is not None:
        out["split"] = {}
        n_seeds = len(views)
        for m in sorted({1, n_seeds - 1}):
            values = [
                split_converged(
                    x, views[j], np.concatenate([views[(j + i) % n_seeds] for i in range(1, m + 1)], axis=1)
                )
                for j, x in enumerate(errors)
            ]
            out["split"][m] = {"pool_rays": m * S, "converged": spread(values)}
    return out


def main(argv=None) -> dict:
    import convergence as cv

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    cv.add_cell_arguments(ap, seeds=10, bake_spp=32, glossy_spp=64)
    ap.add_argument(
        "--budgets", type=int, nargs="+", default=[8, 16, 32], help="mean rays a pixel, each in [2, S]"
    )
    args = ap.parse_args(argv)
    if args.seeds < 2 or args.bake_spp < 1 or args.glossy_ref_spp < 1 or args.glossy_spp < 8:
        ap.error(
            "--seeds must be at least 2, --bake-spp and --glossy-ref-spp at least 1, --glossy-spp at least 8"
        )
    if any(not MIN_RAYS <= k <= args.glossy_spp for k in args.budgets):
        ap.error(f"--budgets must each lie in [{MIN_RAYS}, --glossy-spp={args.glossy_spp}]")
    b, pos = cv.cell_bench_of(ap, args)

    from probeplace.evaluate import shade_probes
    from probeplace.probes import glossy_maps

    errors, blacks, views = [], [], []
    for seed in range(args.seeds):
        t0 = time.perf_counter()
        lf, _ = b.bake(pos, args.res, seed)
        _, prim, crn, _ = b.steps(seed)
        maps = glossy_maps(lf, b.config.glossy_filter, include_emission=False)
        g = shade_probes(b.scene, lf, prim, b.config, maps=maps).glossy
        S = prim.spp
        errors.append(per_ray(prim.w_glossy, g, crn.radiance, S))  # w (L_probe − L_ref)
        blacks.append(per_ray(prim.w_glossy, np.zeros_like(g), crn.radiance, S))
        views.append(per_ray(prim.w_glossy, crn.radiance, crn.diffuse_at_hit, S))  # w (L_ref − L_diffuse)
        del b.shared[seed]  # this seed's reference is not needed again
        print(f"seed {seed}: baked, shaded and referenced in {time.perf_counter() - t0:.0f} s", flush=True)
    result = {
        "grid": args.grid,
        "seeds": args.seeds,
        "bake_spp": args.bake_spp,
        "glossy_ref_spp": args.glossy_ref_spp,
        "glossy_spp": args.glossy_spp,
    } | spreads(errors, blacks, args.budgets, views)
    pct = lambda d: f"{100 * d['cv']:5.1f} % [{100 * d['ci95'][0]:.1f}, {100 * d['ci95'][1]:.1f}]"
    for k, d in result["uniform"].items():
        print(f"uniform {k:>4} rays a pixel: plain {pct(d['plain'])}, converged {pct(d['converged'])}")
    for kind, rows in result["allocated"].items():
        for budget, d in rows.items():
            print(f"allocated by {kind:<5} {budget:>4} rays a pixel: converged {pct(d['converged'])}")
    for m, d in result["split"].items():
        print(f"split, view dependence from {m} other seeds' rays: converged {pct(d['converged'])}")
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    main()
