"""What a user waits for in a fresh process, with JAX's persistent compilation cache cold and warm (issue 32).

Three commands, each run twice in fresh processes sharing one cache folder that starts empty (``cold``: the
first run compiles and fills it; ``warm``: the second loads from it):

* ``place``: ``probeplace place cornell_box --method grid --budget 4``;
* ``evaluate``: ``probeplace evaluate`` of those probes on the Cornell box at its smallest settings
  (16×16 pixels, 4 spp, 8² maps, 1 bake path, JAX backend);
* ``runner``: one ``experiments/run.py`` run (``bake=none eval=none placer.budget=2``, as
  tests/experiment/test_resume.py sweeps).

Per run: ``wall_s`` (the whole process, interpreter start included, as the parent sees it), ``cpu_s``
(user + system of the child), ``compile_s`` (XLA compilation or, warm, loading the compiled program: the sum
of JAX's ``/jax/core/compile/backend_compile_duration`` events), ``trace_lower_s`` (tracing and lowering to
MLIR, which a warm cache does not save: ``jaxpr_trace_duration`` + ``jaxpr_to_mlir_module_duration``),
``cache_hits`` / ``cache_writes`` (``/jax/compilation_cache/cache_hits`` / ``cache_misses`` events).
Also ``probeplace --help`` and ``probeplace export`` (glTF) wall time, median of 5. The issue's targets are
set beside the figures (``targets``: value, limit, met). Run: ``.venv/bin/python benchmarks/startup.py``.
Last stdout line: JSON, also written to ``benchmarks/results/startup.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent
REPO = ROOT.parent

# The child: JAX's monitoring events summed, the command run in-process, the sums written to $STARTUP_STATS.
CHILD = """
import json, os, runpy, sys
from jax import monitoring

sums = {"compile_s": 0.0, "trace_lower_s": 0.0, "cache_hits": 0, "cache_writes": 0}
KEYS = {"/jax/core/compile/backend_compile_duration": "compile_s",
        "/jax/core/compile/jaxpr_trace_duration": "trace_lower_s",
        "/jax/core/compile/jaxpr_to_mlir_module_duration": "trace_lower_s"}
COUNTS = {"/jax/compilation_cache/cache_hits": "cache_hits",
          "/jax/compilation_cache/cache_misses": "cache_writes"}

def on_duration(event, secs, **kw):
    if event in KEYS:
        sums[KEYS[event]] += secs

def on_event(event, **kw):
    if event in COUNTS:
        sums[COUNTS[event]] += 1

monitoring.register_event_duration_secs_listener(on_duration)
monitoring.register_event_listener(on_event)
kind, argv = sys.argv[1], sys.argv[2:]
rc = 1
try:
    if kind == "cli":
        from probeplace.cli import main
        rc = main(argv)
    else:
        sys.argv = [kind, *argv]
        try:
            runpy.run_path(kind, run_name="__main__")
            rc = 0
        except SystemExit as e:
            rc = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
finally:
    sums["rc"] = rc
    with open(os.environ["STARTUP_STATS"], "w") as f:
        json.dump(sums, f)
sys.exit(rc)
"""

TARGETS = {  # issue 32: name -> limit (value <= limit)
    "warm_evaluate_compile_s": 1.0,
    "warm_place_compile_s": 0.5,
    "warm_over_cold_evaluate_wall": 0.3,
    "help_wall_s": 0.5,
    "export_wall_s": 1.0,
}


def _cpu_children() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _run(cmd: list[str], cache: Path | str, work: Path, stats: Path | None = None) -> dict:
    """Run ``cmd`` in a fresh process with the cache at ``cache``: wall and CPU seconds (+ the child's
    JAX figures when ``stats``)."""
    env = {**os.environ, "PROBEPLACE_JAX_CACHE": str(cache), "PYTHONPATH": str(REPO)}
    if stats is not None:
        env["STARTUP_STATS"] = str(stats)
    cpu0, t0 = _cpu_children(), time.perf_counter()
    r = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True, timeout=1800)
    wall, cpu = time.perf_counter() - t0, _cpu_children() - cpu0
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd[-12:]))}: status {r.returncode}\n{r.stderr[-3000:]}")
    out = {"wall_s": wall, "cpu_s": cpu}
    if stats is not None:
        out.update(json.loads(stats.read_text()))
        out.pop("rc", None)
    return out


def _cold_warm(name: str, make_cmd, tmp: Path) -> dict:
    """``make_cmd(i)`` run twice on one cache folder that starts empty."""
    cache = tmp / f"cache_{name}"
    cache.mkdir(mode=0o700)
    runs = {}
    for i, phase in enumerate(("cold", "warm")):
        runs[phase] = _run(make_cmd(i), cache, tmp, stats=tmp / f"{name}_{phase}.json")
        r = runs[phase]
        print(f"{name:8s} {phase}: wall {r['wall_s']:6.2f} s  cpu {r['cpu_s']:6.2f} s  compile "
              f"{r['compile_s']:6.2f} s  trace+lower {r['trace_lower_s']:5.2f} s  hits {r['cache_hits']}",
              file=sys.stderr, flush=True)  # fmt: skip
    return runs


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="runs of --help and export (median)")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from _common import env_info, write_result

    py = sys.executable
    with tempfile.TemporaryDirectory(prefix="probeplace-startup-") as d:
        tmp = Path(d)
        child = [py, "-c", CHILD]
        place_args = "cli -q place cornell_box --method grid --budget 4 --out".split()
        place = _cold_warm("place", lambda i: [*child, *place_args, str(tmp / f"probes{i}.json")], tmp)
        probes = tmp / "probes0.json"
        eval_args = (
            "cli -q evaluate --scene cornell_box --width 16 --height 16 --spp 4 --glossy-spp 1 --max-depth 3 "
            "--radiance-res 8 --geometry-res 8 --bake-spp 1 --backend jax --probes"
        ).split()
        evaluate = _cold_warm(
            "evaluate", lambda i: [*child, *eval_args, str(probes), "--out", str(tmp / f"eval{i}")], tmp
        )
        run_args = "name=startup bake=none eval=none placer.budget=2 progress=false".split()
        runner = _cold_warm(
            "runner",
            lambda i: [
                *child,
                str(REPO / "experiments" / "run.py"),
                *run_args,
                f"results_dir={tmp / f'results{i}'}",
                f"hydra.run.dir={tmp / f'hydra{i}'}",
            ],
            tmp,
        )
        warm_cache = tmp / "cache_place"
        help_runs = [_run([py, "-m", "probeplace", "--help"], warm_cache, tmp) for _ in range(args.repeats)]
        export = [py, "-m", "probeplace", "export", str(probes), "--format", "gltf", "--out"]
        export_runs = [_run([*export, str(tmp / f"p{k}.glb")], warm_cache, tmp) for k in range(args.repeats)]
    help_wall = statistics.median(r["wall_s"] for r in help_runs)
    export_wall = statistics.median(r["wall_s"] for r in export_runs)
    figures = {
        "warm_evaluate_compile_s": evaluate["warm"]["compile_s"],
        "warm_place_compile_s": place["warm"]["compile_s"],
        "warm_over_cold_evaluate_wall": evaluate["warm"]["wall_s"] / evaluate["cold"]["wall_s"],
        "help_wall_s": help_wall,
        "export_wall_s": export_wall,
    }
    result = {
        "benchmark": "startup",
        "place": place,
        "evaluate": evaluate,
        "runner": runner,
        "help_wall_s": help_wall,
        "export_wall_s": export_wall,
        "help_cpu_s": statistics.median(r["cpu_s"] for r in help_runs),
        "export_cpu_s": statistics.median(r["cpu_s"] for r in export_runs),
        "warm_over_cold_wall": {
            k: v["warm"]["wall_s"] / v["cold"]["wall_s"]
            for k, v in (("place", place), ("evaluate", evaluate), ("runner", runner))
        },
        "targets": {
            k: {"value": figures[k], "limit": lim, "met": figures[k] <= lim} for k, lim in TARGETS.items()
        },
        "settings": {
            "repeats": args.repeats,
            "place": "cornell_box grid budget 4",
            "evaluate": "16x16, spp 4, glossy-spp 1, max-depth 3, maps 8², bake-spp 1, jax",
            "runner": "bake=none eval=none placer.budget=2",
        },
        "env": env_info(),
    }
    write_result("startup", result)
    return result


if __name__ == "__main__":
    main()
