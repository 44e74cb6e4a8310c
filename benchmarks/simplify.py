"""Baseline benchmarks (issue 6): Vardis 2021 simplification times, Sponza LOD / uniform probe counts.

``vardis_108_to_62_s``: 108 dense probes (6×3×6 grid, Cornell box), 128 surface evaluation points, down to
62 (the authors' Unity prototype took 40.39 s on this task: issue 6, not measured here).
``vardis_4096_to_10pct_s``: 4,096 probes (16³ grid, Cornell box), 10,000 surface evaluation points, down to
410, one removal per iteration (the paper's loop); ``..._batched_s`` removes independent sets of up to 5 %
of the probes per iteration; ``..._lazy_s`` is the lazy greedy (stale scores re-evaluated only at the
head of the ranking). Times cover the simplification only; the 108 case is the median of 5 repeats
after a warm-up call that compiles (``*_compile_s``); the 4,096 runs are single calls (the scoring kernel
is already compiled for most shapes by then, so they include little compile time). ``*_cpu_s`` is
process CPU time (all threads), a load-independent companion of the wall times on a shared machine.
Probe values (path-traced SH) are timed apart (``*_values_s``).

Run: ``.venv/bin/python benchmarks/simplify.py [--quick]``; last stdout line is the JSON result, also in
``benchmarks/results/simplify.json``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import env_info, setup_scene_path, timed, write_result


def _setup(scene, dims, n_eval, *, n_dirs, spp, seed):
    import jax
    import numpy as np

    from probeplace.placement import dense_probe_sh, evaluation_points, uniform_probe_grid

    r = uniform_probe_grid(scene, dims=dims, inside="relocate")
    pos = np.asarray(r.probes.pos_world)[np.asarray(r.probes.active)]
    t_val, values = timed(
        lambda: dense_probe_sh(scene, pos, n_dirs=n_dirs, spp=spp, max_depth=4, key=jax.random.key(seed))
    )
    pts = evaluation_points(scene, n_eval, key=jax.random.key(seed + 1), kind="surface")
    return pos, np.asarray(values), pts, t_val


def _time_simplify(pos, values, pts, target, repeats, **kw):
    """(median wall s, compile s, median process CPU s, result): one warm-up call compiles."""
    import time

    import numpy as np

    from probeplace.placement import vardis_simplify

    c0 = time.process_time()
    t_first, res = timed(lambda: vardis_simplify(pos, values, pts, target=target, **kw))
    cpu_first = time.process_time() - c0
    wall, cpu = [], []
    for _ in range(repeats):
        c0 = time.process_time()
        wall.append(timed(lambda: vardis_simplify(pos, values, pts, target=target, **kw))[0])
        cpu.append(time.process_time() - c0)
    if not wall:  # no repeat: the first call's times, compile included
        return t_first, 0.0, cpu_first, res
    med = float(np.median(wall))
    return med, max(0.0, t_first - med), float(np.median(cpu)), res


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="skip the 4,096-probe runs")
    args = ap.parse_args()
    setup_scene_path()
    import numpy as np

    from probeplace._core import ProbeplaceError, scene_box
    from probeplace.placement import lod_probe_grid, uniform_probe_grid
    from probeplace.scene import load_scene

    out: dict = {"env": env_info(), "unity_prototype_108_to_62_s_quoted": 40.39}
    cornell = load_scene("cornell_box")

    pos, vals, pts, t_val = _setup(cornell, (6, 3, 6), 128, n_dirs=64, spp=4, seed=0)
    assert len(pos) == 108
    med, comp, cpu, res = _time_simplify(pos, vals, pts, 62, 5)
    med_l, _, cpu_l, res_l = _time_simplify(pos, vals, pts, 62, 5, lazy=True)
    out.update(
        vardis_108_to_62_lazy_s=med_l,
        vardis_108_to_62_lazy_cpu_s=cpu_l,
        vardis_108_to_62_lazy_error=res_l.error,
        vardis_108_to_62_s=med,
        vardis_108_to_62_cpu_s=cpu,
        vardis_108_to_62_compile_s=comp,
        vardis_108_values_s=t_val,
        vardis_108_to_62_error=res.error,
        vardis_108_to_62_kept=int(res.keep.sum()),
    )
    print(f"108 -> 62: {med:.3f} s (compile {comp:.2f} s), error {res.error:.4f}", flush=True)

    if not args.quick:
        pos, vals, pts, t_val = _setup(cornell, (16, 16, 16), 10_000, n_dirs=64, spp=2, seed=1)
        assert len(pos) == 4096
        out["vardis_4096_values_s"] = t_val
        med, comp, cpu, res = _time_simplify(pos, vals, pts, 410, 0)
        out.update(
            vardis_4096_to_10pct_s=med,
            vardis_4096_to_10pct_cpu_s=cpu,
            vardis_4096_to_10pct_compile_s=comp,
            vardis_4096_to_10pct_error=res.error,
            vardis_4096_to_10pct_scored=res.n_scored,
        )
        print(f"4096 -> 410: {med:.1f} s, error {res.error:.4f}", flush=True)
        med, comp, cpu, res = _time_simplify(pos, vals, pts, 410, 0, per_iteration=0.05)
        out.update(
            vardis_4096_to_10pct_batched_s=med,
            vardis_4096_to_10pct_batched_cpu_s=cpu,
            vardis_4096_to_10pct_batched_error=res.error,
            vardis_4096_to_10pct_batched_iterations=res.n_iterations,
        )
        print(f"4096 -> 410 batched: {med:.1f} s, error {res.error:.4f}", flush=True)
        med, comp, cpu, res = _time_simplify(pos, vals, pts, 410, 0, lazy=True)
        out.update(
            vardis_4096_to_10pct_lazy_s=med,
            vardis_4096_to_10pct_lazy_cpu_s=cpu,
            vardis_4096_to_10pct_lazy_error=res.error,
            vardis_4096_to_10pct_lazy_scored=res.n_scored,
        )
        print(f"4096 -> 410 lazy: {med:.1f} s, error {res.error:.4f}", flush=True)
    else:
        for k in ("vardis_4096_to_10pct_s", "vardis_4096_to_10pct_batched_s", "vardis_4096_to_10pct_lazy_s"):
            out[k] = None
        out["vardis_4096_reason"] = "skipped (--quick)"

    try:
        sponza = load_scene("crytek_sponza")
    except ProbeplaceError as e:
        out.update(sponza_lod_probes=None, sponza_uniform_probes=None, sponza_reason=f"scene absent: {e}")
    else:
        t0 = time.perf_counter()
        g = lod_probe_grid(sponza, base_divisions=(5, 3, 3), sub_division_level=3)
        out["sponza_lod_s"] = time.perf_counter() - t0
        out["sponza_lod_probes"] = g.probe_count
        out["sponza_lod_levels"] = np.bincount(g.levels, minlength=4).tolist()
        u = uniform_probe_grid(None, bounds=scene_box(sponza), dims=(40, 24, 24), inside="keep")
        out["sponza_uniform_probes"] = u.probes.capacity
    write_result("simplify", out)


if __name__ == "__main__":
    main()
