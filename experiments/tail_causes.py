"""What the glossy error's tail is made of, ray by ray (issue 33: what makes the seed spread)

Reruns one cell of ``benchmarks/convergence.py`` (the same bake, rays, reference and trace: its glossy MSE
repeats the cell's) and charges each glossy ray's share of the squared error (``evaluate.sample_charges``:
its error times its pixel's, so the charges add up exactly) to one cause:

* ``miss``, ``unresolved``: the tracer's status;
* ``wrong hit``: a resolved hit not at the exact one (``evaluate.agreeing_hits``, the cell's agreement);
* at an agreeing hit, two additive parts of the ray's error w (L_probe − L_ref):
  ``view dependence``, w (L_diffuse − L_ref), the reference's specular lobe at the hit that no probe stores
  (``CrnReference.diffuse_at_hit``), and the probe's read against the diffuse lobe, w (L_probe − L_diffuse),
  split by its sign: ``read too bright`` / ``read too dark`` (luminance).

It prints each cause's share of the tail's squared error (the ``--top`` % of pixels with the largest,
``evaluate.tail_count`` of them: at 1 % the metrics' ``top_percent_share`` pixels) and of the whole MSE.
``--ref-spp N`` adds an independent CRN reference of N paths a ray: the MSE and tail share against it,
and the MSE of the cell's reference against it (the noise the reference adds, which its noise floor
estimates). ``--show K`` lists the K worst pixels' largest ray.

    PROBEPLACE_SCENE_PATH=../shared/scenes .venv/bin/python experiments/tail_causes.py \\
        --grid 8x4x4 --seed 0 --ref-spp 64 --show 10

Last stdout line: one JSON object.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))

CAUSES = ("miss", "unresolved", "wrong hit", "view dependence", "read too bright", "read too dark")


def _lum(rgb: np.ndarray) -> np.ndarray:
    """Rec. 709 luminance (``_core.luminance``) of a host array, back on the host (for signs and display)."""
    import jax.numpy as jnp

    from probeplace._core import luminance

    return np.asarray(luminance(jnp.asarray(rgb)), np.float64)


def tail_causes(w, l_probe, l_ref, l_diffuse, status, agree, spp: int, top_percent: float = 1.0) -> dict:
    """Each cause's share (``CAUSES``) of the squared glossy error of the ``top_percent`` % of pixels with the
    largest (``tail``) and of all pixels (``all``); the shares of each add up to 1 (module docstring).

    Args:
        w: (n, 3) estimator weights (0 where a sample has no glossy ray); n = pixels × ``spp``, pixel-major.
        l_probe, l_ref, l_diffuse: (n, 3) radiance read from the probes, the CRN reference, and the CRN
            reference with the diffuse lobe only at the hit.
        status: (n,) tracer status (``probes.TraceStatus``; other values: no ray).
        agree: (n,) the ray is an agreeing hit (``evaluate.agreeing_hits``).

    Raises:
        ValueError: a sample with a weight has no traced ray (its error would go to no cause).
    """
    from probeplace.evaluate import sample_charges, sample_errors, tail_count, top_share
    from probeplace.probes import TraceStatus

    e_s, e_px = sample_errors(w, l_probe, l_ref, spp)
    part_view = sample_errors(w, l_diffuse, l_ref, spp)[0]
    part_read = e_s - part_view
    st = np.asarray(status)
    agree = np.asarray(agree, bool) & (st == TraceStatus.HIT)
    traced = np.isin(st, [TraceStatus.MISS, TraceStatus.HIT, TraceStatus.UNRESOLVED])
    if np.any(~traced & np.any(np.asarray(w) != 0, axis=1)):
        raise ValueError(
            "a sample without a traced ray (status other than miss, hit, unresolved) has a weight"
        )
    bright = _lum(np.asarray(l_probe) - np.asarray(l_diffuse)) > 0
    whole, view, read = (sample_charges(e, e_px) for e in (e_s, part_view, part_read))
    charge = {
        "miss": np.where(st == TraceStatus.MISS, whole, 0.0),
        "unresolved": np.where(st == TraceStatus.UNRESOLVED, whole, 0.0),
        "wrong hit": np.where((st == TraceStatus.HIT) & ~agree, whole, 0.0),
        "view dependence": np.where(agree, view, 0.0),
        "read too bright": np.where(agree & bright, read, 0.0),
        "read too dark": np.where(agree & ~bright, read, 0.0),
    }
    sq_px = np.mean(e_px**2, axis=1)
    k = tail_count(sq_px.size, top_percent)
    tail_px = np.zeros(sq_px.size, bool)
    tail_px[np.argsort(sq_px, kind="stable")[::-1][:k]] = True
    out = {"mse": float(sq_px.mean()), "tail_pixels": k, "tail_share": top_share(sq_px, k)}
    for name, px in (("tail", tail_px), ("all", np.ones_like(tail_px))):
        rows = np.repeat(px, spp)
        total = float(whole[rows].sum())
        out[name] = {c: float(v[rows].sum() / total) for c, v in charge.items()}
    return out


def _worst(w, l_probe, l_ref, l_diffuse, l_hi, status, agree, spp: int, k: int) -> list[dict]:
    """The ``k`` pixels with the largest squared error: each one's ray with the largest luminance error."""
    from probeplace.evaluate import sample_errors

    e_s, e_px = sample_errors(w, l_probe, l_ref, spp)
    sq, e = np.mean(e_px**2, axis=1), _lum(e_s)
    lum = lambda a, j: float(_lum(np.asarray(a)[j]))
    rows = []
    for p in np.argsort(sq, kind="stable")[::-1][:k]:
        j = p * spp + int(np.argmax(np.abs(e[p * spp : (p + 1) * spp])))
        rows.append(
            {"pixel": int(p), "sq_error": float(sq[p]), "status": int(status[j]), "agreeing": bool(agree[j]),
             "w": lum(w, j), "probe": lum(l_probe, j), "reference": lum(l_ref, j),
             "diffuse_at_hit": lum(l_diffuse, j)}
            | ({"reference_hi": lum(l_hi, j)} if l_hi is not None else {})
        )  # fmt: skip
    return rows


def main(argv=None) -> dict:
    from probeplace._core import TEXEL_RAYS

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--grid",
        default="8x4x4",
        help="uniform grid NxMxK (a convergence cell's), or auto: the cell of the automatic skeleton set "
        "(its placement cached by benchmarks/convergence.py, else placed first: minutes)",
    )
    ap.add_argument("--seed", type=int, default=0, help="bake, reference and evaluation seed")
    ap.add_argument("--res", type=int, default=64, help="radiance map resolution")
    ap.add_argument("--bake-spp", type=int, default=8)
    ap.add_argument("--geometry-res", type=int, default=512)
    ap.add_argument(
        "--texel-rays",
        default="surfel",
        choices=TEXEL_RAYS,
        help="where a radiance texel's rays leave (probes.BakeConfig.texel_rays; default as "
        "benchmarks/convergence.py's)",
    )
    ap.add_argument(
        "--filter",
        default=None,
        help="the glossy read's filter (EvalConfig.glossy_filter; default: the cell's)",
    )
    ap.add_argument("--top", type=float, default=1.0, help="the tail: this percentage of the pixels")
    ap.add_argument("--ref-spp", type=int, default=0, help="an independent CRN reference of N paths a ray")
    ap.add_argument("--show", type=int, default=0, metavar="K", help="list the K worst pixels' largest ray")
    args = ap.parse_args(argv)
    if not 0 < args.top <= 100 or args.ref_spp < 0 or args.show < 0:
        ap.error("--top must lie in (0, 100], --ref-spp and --show must not be negative")

    import convergence as cv

    if args.grid != "auto" and not cv.is_grid(args.grid):
        ap.error(f"--grid {args.grid!r}: want NxMxK, e.g. 8x4x4, or auto")

    from probeplace._core import ConfigError
    from probeplace.evaluate import (
        agreeing_hits,
        agreement_atol,
        crn_reference,
        perfect_trace,
        sample_errors,
        shade_probes,
    )
    from probeplace.probes import glossy_maps

    grid = "8x4x4" if args.grid == "auto" else args.grid  # the benchmark's arguments want a grid
    b = cv.sponza_cell_bench_or_exit(ap, grid, args.res, args.bake_spp, args.geometry_res, args.texel_rays)
    if args.filter:
        try:
            b.config = dataclasses.replace(b.config, glossy_filter=args.filter)
        except ConfigError as e:
            ap.error(str(e))
    if args.grid == "auto":
        pos = b.auto_positions(args.seed)[0]  # placed with the cell's seed, as the benchmark's auto cell
    else:
        pos = cv.grid_positions(b.scene, cv.dims_of(args.grid))
    lf, _ = b.bake(pos, args.res, args.seed)
    _, prim, crn, _ = b.steps(args.seed)
    maps = glossy_maps(lf, b.config.glossy_filter, include_emission=False)
    sh = shade_probes(b.scene, lf, prim, b.config, maps=maps)
    exact = perfect_trace(lf, prim, b.config, caster=b.caster, maps=maps)
    agree = agreeing_hits(
        sh.t, exact.t_exact, sh.status, rtol=b.config.agreement_rtol, atol=agreement_atol(b.scene)
    )
    S, w = prim.spp, prim.w_glossy
    out = {
        "grid": args.grid,
        "seed": args.seed,
        "filter": b.config.glossy_filter,
        "texel_rays": args.texel_rays,
    } | tail_causes(w, sh.glossy, crn.radiance, crn.diffuse_at_hit, sh.status, agree, S, args.top)
    hi = None
    if args.ref_spp:
        cfg = dataclasses.replace(b.config, glossy_ref_spp=args.ref_spp)
        hi = crn_reference(b.scene, prim, cfg, seed=args.seed + 1, caster=b.caster).radiance  # other paths
        against = tail_causes(w, sh.glossy, hi, crn.diffuse_at_hit, sh.status, agree, S, args.top)
        e_ref = sample_errors(w, crn.radiance, hi, S)[1]
        out["against_ref_hi"] = {
            "ref_spp": args.ref_spp,
            "mse": against["mse"],
            "tail_share": against["tail_share"],
        }
        out["reference_noise_mse"] = float(np.mean(e_ref**2))
    if args.show:
        out["worst"] = _worst(
            w, sh.glossy, crn.radiance, crn.diffuse_at_hit, hi, sh.status, agree, S, args.show
        )

    print(f"{args.grid} seed {args.seed}: glossy MSE {out['mse']:.3g}, its {out['tail_pixels']} worst pixels "
          f"{100 * out['tail_share']:.0f} % of it")  # fmt: skip
    print(f"{'cause':<18}{'share of the tail':>20}{'share of the MSE':>18}")
    for c in CAUSES:
        print(f"{c:<18}{100 * out['tail'][c]:>19.1f}%{100 * out['all'][c]:>17.1f}%")
    if hi is not None:
        a = out["against_ref_hi"]
        print(f"against a {args.ref_spp}-path reference: MSE {a['mse']:.3g}, "
              f"tail {100 * a['tail_share']:.0f} %; "
              f"the cell's reference against it: {out['reference_noise_mse']:.3g}")  # fmt: skip
    for r in out.get("worst", []):
        print("  " + ", ".join(f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}" for k, v in r.items()))
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
