"""Peak resident memory of baking and light-field tracing against problem size (issue 9).

Every measurement runs in a fresh subprocess and reads ``resource.getrusage(RUSAGE_SELF).ru_maxrss`` in
that child at the end (the high-water mark of the whole process: imports, compiles, buffers). Sizes:

* ``idle``: import probeplace + JAX and run one tiny jitted op (the baseline every other figure includes);
* ``bake``: the Cornell box, N and 4N probes, 32² maps, path-traced radiance, the same
  ``probes_per_batch`` (the bake's chunk);
* ``trace``: light-field tracing of R and 4R random rays through 8 baked probes, the same ``chunk``; also
  unchunked (``chunk=None``) for comparison.

``peak_rss_growth_ratio`` is the largest peak(4×)/peak(1×) over the chunked stages (issue 9: at most 2).
Run: ``.venv/bin/python benchmarks/memory.py`` (``--quick`` for smaller sizes). Last stdout line: JSON,
also written to ``benchmarks/results/memory.json``.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent


def _peak_bytes() -> int:
    # Linux reports ru_maxrss in KiB (macOS in bytes)
    r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(r) if sys.platform == "darwin" else int(r) * 1024


def _child(stage: str, size: int, chunk: int | None) -> dict:
    import jax
    import jax.numpy as jnp
    import numpy as np

    t0 = time.perf_counter()
    if stage == "idle":
        jax.block_until_ready(jax.jit(lambda x: x + 1)(jnp.zeros(4)))
        return {"peak_rss_bytes": _peak_bytes(), "seconds": time.perf_counter() - t0}

    from probeplace._core import ProbeSet, scene_box
    from probeplace.geometry import BruteForceCaster
    from probeplace.probes import (
        BakeConfig,
        bake_probes,
        make_tracer,
        path_traced_radiance,
        trace_light_field,
    )
    from probeplace.scene import cornell_box

    scene = cornell_box()
    lo, hi = scene_box(scene)
    rng = np.random.default_rng(0)
    caster = BruteForceCaster(scene)
    if stage == "bake":
        # probes in the free upper part of the box (above both blocks)
        pos = lo + rng.uniform([0.1, 0.65, 0.1], [0.9, 0.95, 0.9], (size, 3)) * (hi - lo)
        probes = ProbeSet(pos_world=jnp.asarray(pos, jnp.float32), active=jnp.ones(size, bool))
        cfg = BakeConfig(radiance_res=32, irradiance_res=8, moments_res=16, n_sub=1, probes_per_batch=chunk,
                         progress=False)  # fmt: skip
        fn = path_traced_radiance(scene, spp=1, max_depth=3, caster=caster)
        lf = bake_probes(scene, probes, caster=caster, radiance_fn=fn, key=jax.random.key(0), config=cfg)
        jax.block_until_ready(lf)
        return {"peak_rss_bytes": _peak_bytes(), "seconds": time.perf_counter() - t0}
    if stage == "trace":
        pos = lo + rng.uniform([0.1, 0.65, 0.1], [0.9, 0.95, 0.9], (8, 3)) * (hi - lo)
        probes = ProbeSet(pos_world=jnp.asarray(pos, jnp.float32), active=jnp.ones(8, bool))

        def const(o, d, k):
            return jnp.full((o.shape[0], 3), 0.5, o.dtype), jnp.zeros((o.shape[0], 3), o.dtype)

        cfg = BakeConfig(radiance_res=32, irradiance_res=4, moments_res=4, n_sub=1, progress=False)
        lf = bake_probes(scene, probes, caster=caster, radiance_fn=const, key=jax.random.key(0), config=cfg)
        tr = make_tracer(lf, scene.bounds)
        o = jnp.asarray(lo + rng.uniform(0.05, 0.95, (size, 3)) * (hi - lo), jnp.float32)
        d = rng.normal(size=(size, 3))
        d = jnp.asarray(d / np.linalg.norm(d, axis=1, keepdims=True), jnp.float32)
        res = trace_light_field(tr, o, d, chunk=chunk)
        jax.block_until_ready(res)
        return {
            "peak_rss_bytes": _peak_bytes(),
            "seconds": time.perf_counter() - t0,
            "hit_share": float(np.mean(np.asarray(res.status) == 1)),
        }
    raise SystemExit(f"unknown stage {stage!r}")


def _measure(stage: str, size: int, chunk: int | None) -> dict:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", stage, str(size), str(chunk or 0)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=1800, cwd=ROOT.parent)
    if r.returncode != 0:
        raise RuntimeError(f"{stage} {size}: child failed\n{r.stderr[-3000:]}")
    out = json.loads(r.stdout.strip().splitlines()[-1])
    out.update(stage=stage, size=size, chunk=chunk)
    print(f"{stage:6s} size={size:<8d} chunk={chunk!s:<6s} peak={out['peak_rss_bytes'] / 2**20:8.1f} MiB  "
          f"{out['seconds']:.1f} s", file=sys.stderr, flush=True)  # fmt: skip
    return out


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--child", nargs=3, metavar=("STAGE", "SIZE", "CHUNK"), help=argparse.SUPPRESS)
    ap.add_argument("--quick", action="store_true", help="smaller sizes (a smoke run)")
    args = ap.parse_args(argv)
    if args.child:
        stage, size, chunk = args.child
        print(json.dumps(_child(stage, int(size), int(chunk) or None)))
        return {}

    sys.path.insert(0, str(ROOT))
    from _common import env_info, write_result

    n_probes = 8 if args.quick else 32
    n_rays = 1 << (14 if args.quick else 16)
    bake_chunk, trace_chunk = 4, 4096
    idle = _measure("idle", 0, None)
    runs = {
        "bake": [_measure("bake", n, bake_chunk) for n in (n_probes, 4 * n_probes)],
        "trace": [_measure("trace", n, trace_chunk) for n in (n_rays, 4 * n_rays)],
        "trace_unchunked": [_measure("trace", n, None) for n in (n_rays, 4 * n_rays)],
    }
    base = idle["peak_rss_bytes"]
    ratios, above = {}, {}
    for name, (small, big) in runs.items():
        ratios[name] = big["peak_rss_bytes"] / small["peak_rss_bytes"]
        above[name] = (big["peak_rss_bytes"] - base) / max(small["peak_rss_bytes"] - base, 1)
    result = {
        "benchmark": "memory",
        "idle_jax_peak_rss_bytes": base,
        "runs": {k: [{kk: v for kk, v in r.items()} for r in rs] for k, rs in runs.items()},
        "ratio_4x_over_1x": ratios,
        "ratio_4x_over_1x_above_idle": above,
        "peak_rss_growth_ratio": max(ratios["bake"], ratios["trace"]),
        "limit": 2.0,
        "quick": bool(args.quick),
        "settings": {"bake_probes": [n_probes, 4 * n_probes], "bake_probes_per_batch": bake_chunk,
                     "bake_radiance_res": 32, "trace_rays": [n_rays, 4 * n_rays], "trace_chunk": trace_chunk},
        "env": env_info(),
    }  # fmt: skip
    write_result("memory", result)
    return result


if __name__ == "__main__":
    main()
