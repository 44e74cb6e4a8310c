"""Placement benchmark: Cornell box and Crytek Sponza "auto" budgets (coverage, probe count, time).

Last stdout line: one JSON object, also written to benchmarks/results/placement.json. Times are one cold
run each in a fresh process state (SDF build from the on-disk cache if present, XLA compilation and the
search included), since placement runs once per scene; compile time is not separable from the search's
many small jitted calls and is reported inside ``*_timings``. ``*_place_cpu_s`` is the process CPU time
(all threads) of the same call: on a shared machine the wall time depends on the other jobs, the CPU time
much less. ``visibility`` names the binary-visibility caster of the search (Embree when embreex imports).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import env_info, setup_scene_path, write_result


def run(scene_name: str) -> dict:
    from probeplace.placement import place
    from probeplace.scene import load_scene

    scene = load_scene(scene_name)
    t0, c0 = time.perf_counter(), time.process_time()
    placed = place(scene, budget="auto")
    return {
        "s": time.perf_counter() - t0,
        "cpu_s": time.process_time() - c0,
        "probes": placed.n_probes,
        "meta": placed.metadata,
    }


def main() -> None:
    setup_scene_path()
    out: dict = {"env": env_info()}
    c = run("cornell_box")
    out.update(
        cornell_auto_probes=c["probes"],
        cornell_auto_coverage=c["meta"]["coverage"],
        cornell_place_s=round(c["s"], 2),
        cornell_place_cpu_s=round(c["cpu_s"], 2),
        visibility=c["meta"].get("visibility"),
        cornell_timings=c["meta"]["timings"],
    )
    try:
        s = run("crytek_sponza")
        out.update(
            sponza_place_s=round(s["s"], 2),
            sponza_place_cpu_s=round(s["cpu_s"], 2),
            sponza_n_samples=s["meta"]["n_samples"],
            sponza_n_candidates=s["meta"]["n_candidates"],
            sponza_auto_coverage=s["meta"]["coverage"],
            sponza_auto_probes=s["probes"],
            sponza_timings=s["meta"]["timings"],
        )
    except Exception as e:  # scene absent: report why instead of a number
        out.update(sponza_place_s=None, sponza_auto_coverage=None, sponza_error=f"{type(e).__name__}: {e}")
    write_result("placement", out)


if __name__ == "__main__":
    main()
