"""Reference path tracer vs Mitsuba 3 on the Cornell box (same size, spp, depth), interleaved in one process.

    .venv/bin/python benchmarks/pathtrace.py [--size 256] [--spp 32] [--max-depth 8] [--repeats 3]
        [--schedule compact|fused]

Last stdout line: one JSON object, also written to benchmarks/results/pathtrace.json. Keys:
``cornell_spp_per_s`` (our path samples per second, steady state), ``mitsuba_spp_per_s``,
``cornell_vs_mitsuba`` (ratio, Mitsuba's best variant here named in ``mitsuba_variant``),
``cornell_rel_mse_vs_mitsuba`` (relMSE of our mean image vs Mitsuba's, both averaged over the repeats,
relMSE = mean((a − b)² / (b² + 0.01))) with ``noise_floor`` (the relMSE expected from both images'
variance alone), ``compile_s`` (first call minus a steady call of the same work; compile is not in
the rates), ``bake_texel_samples_per_s`` (path samples per second while baking light-field probes in
the Cornell box: probes × texels × jittered rays × spp over the median bake time, compile apart) with
``bake_compile_s``; ``schedule`` (``RenderConfig.schedule`` of the Cornell render, ``--schedule``;
the bake always uses the default).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import jax
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import env_info, write_result
from probeplace.render import RenderConfig, best_mitsuba_variant, mitsuba_scene_dict, render
from probeplace.scene import cornell_box

EPS_REL = 0.01  # relMSE denominator offset (Rousselle et al. 2011 convention)


def bake_rate(scene, reps: int, n_probes: int = 4, res: int = 16, n_sub: int = 2, spp: int = 16) -> dict:
    """Bake ``n_probes`` probes at ``res``² × ``n_sub``² jittered rays × ``spp`` paths; path samples/s."""
    import jax.numpy as jnp

    from probeplace import ProbeSet
    from probeplace.probes import BakeConfig, bake_probes, path_traced_radiance
    from probeplace.render import default_caster

    lo, hi = (np.asarray(b) for b in scene.bounds)
    pos = lo + (hi - lo) * np.array([[0.3, 0.5, 0.6], [0.7, 0.75, 0.5], [0.5, 0.8, 0.4], [0.5, 0.6, 0.8]])
    probes = ProbeSet(pos_world=jnp.asarray(pos[:n_probes], jnp.float32), active=jnp.ones(n_probes, bool))
    caster = default_caster(scene)
    fn = path_traced_radiance(scene, spp=spp, caster=caster)
    cfg = BakeConfig(radiance_res=res, n_sub=n_sub, probes_per_batch=n_probes, progress=False)

    def bake(seed):
        lf = bake_probes(scene, probes, caster=caster, radiance_fn=fn, key=jax.random.key(seed), config=cfg)
        return jax.block_until_ready(lf.radiance)

    t0 = time.perf_counter()
    bake(10_000)
    first = time.perf_counter() - t0
    times = []
    for r in range(reps):
        t0 = time.perf_counter()
        bake(r)
        times.append(time.perf_counter() - t0)
    med = statistics.median(times)
    samples = n_probes * res * res * n_sub * n_sub * spp
    return {
        "bake_texel_samples_per_s": samples / med,
        "bake_compile_s": max(first - med, 0.0),
        "bake_s_median": med,
        "bake_setup": {"probes": n_probes, "radiance_res": res, "n_sub": n_sub, "spp": spp},
    }


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--schedule", default="compact", help="RenderConfig.schedule: compact or fused")
    args = ap.parse_args(argv)
    size, spp, depth, reps = args.size, args.spp, args.max_depth, args.repeats
    n_samples = size * size * spp

    scene = cornell_box()
    # specular = 0: Lambertian materials, the same BSDF as Mitsuba's `diffuse`.
    cfg = RenderConfig(
        width=size,
        height=size,
        spp=spp,
        max_depth=depth,
        rr_depth=5,
        specular=0.0,
        progress=False,
        schedule=args.schedule,
    )

    import mitsuba as mi

    variant = best_mitsuba_variant()
    with tempfile.TemporaryDirectory() as tmp:
        mi_scene = mi.load_dict(
            mitsuba_scene_dict(
                scene,
                scene.view("front"),
                width=size,
                height=size,
                spp=spp,
                max_depth=depth,
                rr_depth=5,
                workdir=tmp,
            )
        )

    def ours(seed):
        return render(scene, "front", cfg, key=jax.random.key(seed))

    def theirs(seed):
        return np.asarray(mi.render(mi_scene, seed=seed), np.float64)[..., :3]

    # Warm-up (compilation) of both, timed apart: our warm-up renders one batch of samples (the same
    # compiled kernel as the full render), Mitsuba's a full render (its JIT compiles on the first one).
    from probeplace.render._render import _batch_layout

    _, g = _batch_layout(cfg, size * size)
    warm_cfg = RenderConfig(
        width=size, height=size, spp=g, max_depth=depth, specular=0.0, progress=False, schedule=args.schedule
    )
    t0 = time.perf_counter()
    jax.block_until_ready(render(scene, "front", warm_cfg, key=jax.random.key(10_000)).mean)
    first_ours = time.perf_counter() - t0
    t0 = time.perf_counter()
    theirs(10_000)
    first_mi = time.perf_counter() - t0

    t_ours, t_mi, o_means, o_vars, m_imgs = [], [], [], [], []
    for r in range(reps):  # interleaved
        t0 = time.perf_counter()
        res = ours(r)
        jax.block_until_ready(res.mean)
        t_ours.append(time.perf_counter() - t0)
        o_means.append(np.asarray(res.image("full"), np.float64))
        o_vars.append(np.asarray(res.variance("full"), np.float64))
        t0 = time.perf_counter()
        m_imgs.append(theirs(r))
        t_mi.append(time.perf_counter() - t0)

    med_ours, med_mi = statistics.median(t_ours), statistics.median(t_mi)
    a = np.mean(o_means, axis=0)
    var_a = np.mean(o_vars, axis=0) / reps
    b = np.mean(m_imgs, axis=0)
    var_b = np.var(m_imgs, axis=0, ddof=1) / reps if reps > 1 else np.full_like(b, np.nan)
    den = b * b + EPS_REL
    rel_mse = float(np.mean((a - b) ** 2 / den))
    floor = float(np.mean((var_a + var_b) / den))
    result = {
        "cornell_spp_per_s": n_samples / med_ours,
        "mitsuba_spp_per_s": n_samples / med_mi,
        "cornell_vs_mitsuba": med_mi / med_ours,
        "mitsuba_variant": variant,
        "schedule": args.schedule,
        "cornell_rel_mse_vs_mitsuba": rel_mse,
        "noise_floor": floor,
        # First call minus the steady-state time of the same amount of work.
        "compile_s": max(first_ours - med_ours * g / spp, 0.0),
        "mitsuba_compile_s": max(first_mi - med_mi, 0.0),
        "render_s_median": med_ours,
        "mitsuba_render_s_median": med_mi,
        **bake_rate(scene, reps),
        "size": size,
        "spp": spp,
        "max_depth": depth,
        "rr_depth": 5,
        "repeats": reps,
        "samples_per_render": n_samples,
        "env": env_info(),
    }
    write_result("pathtrace", result)
    return result


if __name__ == "__main__":
    main()
