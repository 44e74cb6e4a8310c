"""Light-field tracer throughput, against Embree on one thread on the same rays, and hi-Z vs two-level steps.

    .venv/bin/python benchmarks/tracer.py [--rays N] [--repeats R] [--quick]

Rays are secondary rays as shading makes them: from surface points seen by the scene's first view
(Embree primary hits, offset 1e-4 of the scene size along the normal) into the cosine-weighted
hemisphere. Probes: Cornell box 4×4×4 grid, Sponza 8×4×4 grid (Wang 2019's equal-quality grid), baked
geometry maps at 64² (radiance constant: the tracer reads only distance and normal maps). Compile time
is measured apart (``.lower().compile()``); timings are medians of interleaved repeats (light field,
Embree 1 thread). ``hiz_vs_two_level_steps`` is mean march steps of hi-Z over two-level on the same rays
(Wang 2019 §4.2 reports ≥ 30% fewer steps, i.e. a ratio ≤ 0.7, at 512² maps);
``hiz_vs_two_level_steps_r128`` / ``_r256`` are the same ratio with geometry maps baked at 128² / 256²
(Cornell 4×4×4; ``sponza_…`` the Sponza 8×4×4 grid), from ``hierarchy_steps``.
``sponza_march_s_r512_over_r128`` (issue 33: at most about 2) and ``sponza_march_steps_r512_over_r128``:
the shading's trace (hi-Z, wavefront engine) of the same rays through the Sponza 8×4×4 grid's geometry
maps at 512² over 128², time (median of interleaved repeats, compile apart) and mean march steps
(``march_cost``; details in ``sponza_march_cost``).

``cornell_glossy_mse`` / ``cornell_glossy_noise_floor``: ``probeplace.evaluate.evaluate`` on the Cornell box
"front" view (4×4×4 grid baked with the path tracer, light-field shading; image, spp and map resolution in
``cornell_eval``): the glossy-indirect MSE against the common-random-number reference and that
reference's noise floor (docs/evaluate.md). ``gpu`` is null when ``jax.devices("gpu")`` finds no CUDA
device; with one it holds ``gpu_*`` figures: the 1920×1080-ray trace time and the 1920×1080 glossy-indirect
frame time (one GGX-like secondary ray per pixel traced through the probes and read from the baked maps),
to set beside McGuire 2017's 4.4 ms (Living Room, GTX 1080).

Wavefront engine (``probes/tracer/_wavefront.py``, ``TraceConfig(engine="wavefront")``) on the same rays and
settings as the per-ray hi-Z trace, timed interleaved with it: ``wavefront_vs_reference_cornell`` /
``_sponza`` = its rays/s ÷ the per-ray engine's (medians; target ≥ 10; both engines' rays/s are in
``cornell_*_rays_per_s`` and the per-scene blocks), ``lane_utilisation`` = march steps ÷ executed
lane-steps of the wavefront (the smaller of the two scenes'; target ≥ 0.6), and per scene the rays
whose integer fields differ and the largest difference in t (float32 rounding only:
``wavefront_agreement``). ``sponza_frame_s``: one 160×120 frame of Sponza's first view shaded through the
8×4×4 grid's probes (diffuse irradiance and 8 glossy rays per pixel on the wavefront engine, evaluate's
``shade_probes``), compile apart, median of the repeats (``frame_shading``; details in ``sponza_frame``).
The per-ray engine's time grows faster than the ray count (every vmapped loop waits for the batch's
slowest ray), so the ratio grows with ``--rays``.
Last stdout line: one JSON object, also written to benchmarks/results/tracer.json.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import env_info, setup_scene_path, timed, write_result
from probeplace._core import ProbeSet, SceneError, scene_box
from probeplace.geometry import EmbreeCaster
from probeplace.probes import (
    BakeConfig,
    TraceConfig,
    TraceStatus,
    bake_probes,
    make_tracer,
    trace_light_field,
)
from probeplace.probes.tracer._wavefront import trace_wavefront

#: Every figure of the Sponza part of :func:`main`, null in a run where Sponza does not load (that the two
#: agree, tests/experiment/test_tracer_bench.py).
SPONZA_KEYS = (
    "sponza",
    "sponza_frame",
    "sponza_frame_s",
    "sponza_lf_rays_per_s",
    "sponza_lf_vs_embree_1t",
    "sponza_hiz_vs_two_level_steps",
    "sponza_wavefront_rays_per_s",
    "wavefront_vs_reference_sponza",
    "sponza_hierarchy_steps",
    "sponza_hiz_vs_two_level_steps_r128",
    "sponza_hiz_vs_two_level_steps_r256",
    "sponza_march_cost",
    "sponza_march_s_r512_over_r128",
    "sponza_march_steps_r512_over_r128",
)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def grid_positions(scene, dims):
    lo, hi = scene_box(scene)
    axes = [(np.arange(n) + 0.5) / n for n in dims]
    g = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    return g * (hi - lo) + lo


def shading_rays(scene, caster, n, seed):
    rng = np.random.default_rng(seed)
    cam = scene.views[0]
    pos, look = np.asarray(cam.position, np.float64), np.asarray(cam.look_at, np.float64)
    fwd = _unit(look - pos)
    right = _unit(np.cross(fwd, [0.0, 1.0, 0.0]))
    up = np.cross(right, fwd)
    tan = np.tan(np.radians(float(cam.fov_y_deg)) / 2)
    xy = rng.uniform(-1, 1, (2 * n, 2)) * tan * np.array([16 / 9, 1.0])
    dc = _unit(fwd + xy[:, :1] * right + xy[:, 1:] * up)
    h = caster.closest_hit(np.repeat(pos[None], 2 * n, 0).astype(np.float32), dc.astype(np.float32))
    ok = np.asarray(h.tri) >= 0
    p = (pos + np.asarray(h.t, np.float64)[:, None] * dc)[ok][:n]
    nrm = np.asarray(h.geo_normal, np.float64)[ok][:n]
    nrm = np.where((np.sum(nrm * dc[ok][:n], 1) > 0)[:, None], -nrm, nrm)
    m = len(p)
    u1, u2 = rng.uniform(size=m), rng.uniform(size=m)
    a = np.where(np.abs(nrm[:, :1]) > 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    tx = _unit(np.cross(nrm, a))
    ty = np.cross(nrm, tx)
    r, phi = np.sqrt(u1), 2 * np.pi * u2
    d = (r * np.cos(phi))[:, None] * tx + (r * np.sin(phi))[:, None] * ty + np.sqrt(1 - u1)[:, None] * nrm
    size = float(np.linalg.norm(np.ptp(np.asarray(scene.vertices), axis=0)))
    return (p + 1e-4 * size * nrm).astype(np.float32), _unit(d).astype(np.float32)


def bake_grid(scene, dims, res, caster, radiance_res=None):
    """The grid's probes baked with geometry maps at ``res``² and a constant radiance (at ``res``² too
    unless ``radiance_res`` says: the trace reads only the geometry maps); (probes, bake seconds)."""
    pos = grid_positions(scene, dims)
    probes = ProbeSet(pos_world=jnp.asarray(pos, jnp.float32), active=jnp.ones(len(pos), bool))

    def const(o, d, k):
        return jnp.full((o.shape[0], 3), 0.5, o.dtype), jnp.zeros((o.shape[0], 3), o.dtype)

    cfg = BakeConfig(
        radiance_res=radiance_res or res,
        geometry_res=res,
        irradiance_res=4,
        moments_res=4,
        n_sub=1,
        progress=False,
    )
    t0 = time.perf_counter()
    lf = bake_probes(scene, probes, caster=caster, radiance_fn=const, key=jax.random.key(0), config=cfg)
    return lf, time.perf_counter() - t0


def bench_scene(scene, dims, res, n_rays, repeats, seed=0):
    caster = EmbreeCaster(scene)
    ref = EmbreeCaster(scene, threads=1)
    lf, bake_s = bake_grid(scene, dims, res, caster)
    o_np, d_np = shading_rays(scene, caster, n_rays, seed)
    o, d = jnp.asarray(o_np), jnp.asarray(d_np)
    out: dict = {"rays": len(o_np), "probes": int(np.prod(dims)), "res": res, "bake_s": bake_s}
    steps = {}
    for h in ("hiz", "two_level"):
        tr = make_tracer(lf, scene.bounds, config=TraceConfig(hierarchy=h))
        t0 = time.perf_counter()
        compiled = trace_light_field.lower(tr, o, d).compile()
        out[f"{h}_compile_s"] = time.perf_counter() - t0
        res_ = jax.block_until_ready(compiled(tr, o, d))
        steps[h] = float(np.mean(np.asarray(res_.steps)))
        out[f"{h}_unresolved_share"] = float(np.mean(np.asarray(res_.status) == TraceStatus.UNRESOLVED))
        out[f"{h}_mean_probes_tried"] = float(np.mean(np.asarray(res_.probes_tried)))
        if h == "hiz":
            lf_fn = lambda c=compiled, tr=tr: c(tr, o, d)
            per_ray = res_
    # The wavefront engine, same settings and rays (its stats: executed lane-steps).
    trw = make_tracer(lf, scene.bounds, config=TraceConfig(hierarchy="hiz", engine="wavefront"))
    t0 = time.perf_counter()
    compiled_w = trace_wavefront.lower(trw, o, d).compile()
    out["wavefront_compile_s"] = time.perf_counter() - t0
    wf_fn = lambda: compiled_w(trw, o, d)
    wf, stats = jax.block_until_ready(wf_fn())
    out |= wavefront_agreement(per_ray, wf)
    out["wavefront_lane_utilisation"] = float(np.sum(np.asarray(wf.steps))) / stats.lane_steps()
    out["wavefront_lanes"], out["wavefront_steps_per_chunk"] = list(stats.lanes), stats.steps_per_chunk
    ref_fn = lambda: ref.closest_hit(o_np, d_np)
    ref_fn()
    t_lf, t_wf, t_ref = [], [], []
    for _ in range(repeats):  # interleaved
        t0 = time.perf_counter()
        jax.block_until_ready(lf_fn())
        t_lf.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        jax.block_until_ready(wf_fn())
        t_wf.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        ref_fn()
        t_ref.append(time.perf_counter() - t0)
    out["lf_s"] = statistics.median(t_lf)
    out["wavefront_s"] = statistics.median(t_wf)
    out["embree_1t_s"] = statistics.median(t_ref)
    out["lf_rays_per_s"] = len(o_np) / out["lf_s"]
    out["wavefront_rays_per_s"] = len(o_np) / out["wavefront_s"]
    out["wavefront_vs_reference"] = out["wavefront_rays_per_s"] / out["lf_rays_per_s"]
    out["embree_1t_rays_per_s"] = len(o_np) / out["embree_1t_s"]
    out["steps_hiz"], out["steps_two_level"] = steps["hiz"], steps["two_level"]
    return out, lf


def wavefront_agreement(per_ray, wf) -> dict:
    """How far the wavefront engine's answers are from the per-ray engine's: rays whose integer fields
    (status, probe, texel, steps, probes tried, fallback) differ, and the largest difference in t. Both
    can be non-zero through float32 rounding alone: the engines are different XLA programs, contracted
    into FMAs differently (``probes/tracer/_wavefront.py``), and a rounding can move a cell crossing by a
    step."""
    differ = np.zeros(len(np.asarray(per_ray.status)), bool)
    for f in ("status", "probe", "texel", "steps", "probes_tried", "fallback"):
        a, b = np.asarray(getattr(per_ray, f)), np.asarray(getattr(wf, f))
        differ |= (a != b).reshape(len(a), -1).any(axis=1)
    ta, tb = np.asarray(per_ray.t, np.float64), np.asarray(wf.t, np.float64)
    differ |= np.isfinite(ta) != np.isfinite(tb)
    fin = np.isfinite(ta) & np.isfinite(tb)
    return {
        "wavefront_rays_differing": int(differ.sum()),
        "wavefront_max_abs_dt": float(np.max(np.abs(ta[fin] - tb[fin]), initial=0.0)),
    }


def hierarchy_steps(scene, dims, resolutions, n_rays, seed=0) -> dict:
    """Mean march steps of each hierarchy on the same rays, geometry maps baked at each resolution, and
    whether hi-Z and flat give the same answers (the hierarchy is conservative)."""
    caster = EmbreeCaster(scene)
    o_np, d_np = shading_rays(scene, caster, n_rays, seed)
    o, d = jnp.asarray(o_np), jnp.asarray(d_np)
    out = {}
    for res in resolutions:
        lf, _ = bake_grid(scene, dims, res, caster)
        row: dict = {"rays": len(o_np)}
        runs = {}
        for h in ("hiz", "two_level", "flat"):
            tr = make_tracer(lf, scene.bounds, config=TraceConfig(hierarchy=h))
            runs[h] = jax.block_until_ready(trace_light_field(tr, o, d))
            row[f"steps_{h}"] = float(np.mean(np.asarray(runs[h].steps)))
        row["hiz_vs_two_level_steps"] = row["steps_hiz"] / row["steps_two_level"]
        row["hiz_same_status_as_flat"] = float(
            np.mean(np.asarray(runs["hiz"].status) == np.asarray(runs["flat"].status))
        )
        out[f"r{res}"] = row
        del lf
    return out


def march_cost(scene, dims, resolutions, n_rays, repeats, seed=0) -> dict:
    """The march's cost per ray as the geometry maps grow (issue 33: at 512² at most about twice its cost at
    128², with the full hi-Z pyramid): the same rays traced by the shading's tracer (hi-Z, wavefront engine)
    through the grid's geometry maps baked at each resolution (radiance 4²: the trace does not read it).
    Compile apart; the repeats interleaved across resolutions, medians. ``trace_s_ratio`` and
    ``steps_ratio``: the finest resolution's over the coarsest's."""
    caster = EmbreeCaster(scene)
    o_np, d_np = shading_rays(scene, caster, n_rays, seed)
    o, d = jnp.asarray(o_np), jnp.asarray(d_np)
    runs, out = {}, {}
    for res in resolutions:
        lf, bake_s = bake_grid(scene, dims, res, caster, radiance_res=4)
        tr = make_tracer(lf, scene.bounds, config=TraceConfig(hierarchy="hiz", engine="wavefront"))
        t0 = time.perf_counter()
        compiled = trace_wavefront.lower(tr, o, d).compile()
        compile_s = time.perf_counter() - t0
        fn = lambda c=compiled, tr=tr: c(tr, o, d)
        _, (hit, _) = timed(fn)
        runs[res] = (fn, [])
        out[f"r{res}"] = {
            "rays": len(o_np),
            "bake_s": bake_s,
            "compile_s": compile_s,
            "steps": float(np.mean(np.asarray(hit.steps))),
            "unresolved_share": float(np.mean(np.asarray(hit.status) == TraceStatus.UNRESOLVED)),
        }
        del lf
    for _ in range(repeats):  # interleaved: the machines are shared
        for fn, times in runs.values():
            times.append(timed(fn)[0])
    for res, (_, times) in runs.items():
        out[f"r{res}"]["trace_s"] = statistics.median(times)
    lo, hi = f"r{min(resolutions)}", f"r{max(resolutions)}"
    out["trace_s_ratio"] = out[hi]["trace_s"] / out[lo]["trace_s"]
    out["steps_ratio"] = out[hi]["steps"] / out[lo]["steps"]
    return out


def cornell_eval(scene, quick: bool) -> dict:
    """Glossy MSE and noise floor of a 4×4×4 path-traced bake on the Cornell box (docs/evaluate.md)."""
    from probeplace.evaluate import EvalConfig, evaluate
    from probeplace.probes import path_traced_radiance
    from probeplace.render import default_caster

    caster = default_caster(scene)
    res, size, spp, bake_spp = (16, 16, 8, 4) if quick else (32, 32, 32, 16)
    pos = grid_positions(scene, (4, 4, 4))
    probes = ProbeSet(pos_world=jnp.asarray(pos, jnp.float32), active=jnp.ones(len(pos), bool))
    cfg = BakeConfig(radiance_res=res, n_sub=1, probes_per_batch=16, progress=False)
    t0 = time.perf_counter()
    lf = bake_probes(
        scene,
        probes,
        caster=caster,
        radiance_fn=path_traced_radiance(scene, spp=bake_spp, caster=caster),
        key=jax.random.key(0),
        config=cfg,
    )
    bake_s = time.perf_counter() - t0
    config = EvalConfig(width=size, height=size, spp=spp, glossy_spp=4, glossy_ref_spp=4, timing_repeats=3)
    m = evaluate(scene, lf, view="front", config=config, caster=caster).metrics
    keep = (
        "mse_glossy_indirect",
        "noise_floor_glossy_indirect",
        "mse_glossy_indirect_no_crn",
        "mse_diffuse_indirect",
        "noise_floor_diffuse_indirect",
        "mse_full",
        "noise_floor_full",
        "unresolved_share",
        "shading_s_per_frame",
        "shading_compile_s",
        "width",
        "height",
        "spp",
        "glossy_spp",
    )
    return {k: m[k] for k in keep} | {"radiance_res": res, "bake_spp": bake_spp, "bake_s": bake_s}


def frame_shading(scene, lf, caster, *, size=(160, 120), glossy_spp=8, repeats=3) -> dict:
    """Shading of one frame through the probes (``evaluate``'s ``shade_probes``, wavefront engine): diffuse
    irradiance for every primary sample and ``glossy_spp`` glossy rays per pixel traced and read, the
    first view, compile apart (its first run) and the median of ``repeats`` runs. The primary hits come
    from the exact caster beforehand, as in ``evaluate``; ``lf`` is ``bench_scene``'s bake (constant
    radiance: the time does not depend on the colours)."""
    from probeplace.evaluate import EvalConfig
    from probeplace.evaluate._steps import sample_primary, shade_probes

    w, h = size
    config = EvalConfig(
        width=w,
        height=h,
        glossy_spp=glossy_spp,
        timing_repeats=repeats,
        trace=TraceConfig(hierarchy="hiz", engine="wavefront"),
    )
    prim = sample_primary(scene, scene.views[0], config, seed=0, caster=caster)
    shading = shade_probes(scene, lf, prim, config)
    return {
        "width": w,
        "height": h,
        "glossy_spp": glossy_spp,
        "glossy_rays": len(prim.glossy_idx),
        "frame_s": shading.seconds_per_frame,
        "compile_s": shading.compile_seconds,
    }


def gpu_figures(scene, repeats: int) -> dict:
    """1920×1080 rays on the GPU: light-field trace time and glossy-indirect frame time (trace + read)."""
    from probeplace.probes import glossy_radiance

    lf, _ = bake_grid(scene, (4, 4, 4), 64, EmbreeCaster(scene))
    o, d = shading_rays(scene, EmbreeCaster(scene), 1920 * 1080, 1)
    o, d = jnp.asarray(o), jnp.asarray(d)
    tr = make_tracer(lf, scene.bounds)
    c = trace_light_field.lower(tr, o, d).compile()
    jax.block_until_ready(c(tr, o, d))
    glossy = lambda: glossy_radiance(tr, lf, o, d, include_emission=False, chunk=len(o))
    t0 = time.perf_counter()
    jax.block_until_ready(glossy())
    compile_s = time.perf_counter() - t0
    ts, tg = [], []
    for _ in range(repeats):  # interleaved
        t0 = time.perf_counter()
        jax.block_until_ready(c(tr, o, d))
        ts.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        jax.block_until_ready(glossy())
        tg.append(time.perf_counter() - t0)
    return {
        "gpu_cornell_1080p_trace_ms": 1e3 * statistics.median(ts),
        "gpu_cornell_1080p_glossy_ms": 1e3 * statistics.median(tg),
        "gpu_glossy_first_call_s": compile_s,
        "rays": int(o.shape[0]),
        "device": str(jax.devices("gpu")[0]),
    }


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rays", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="2000 rays, 1 repeat")
    args = ap.parse_args(argv)
    if args.quick:
        args.rays, args.repeats = 2000, 1
    setup_scene_path()
    from probeplace.scene import load_scene

    result: dict = {"env": env_info()}
    cornell, _ = bench_scene(load_scene("cornell_box"), (4, 4, 4), 64, args.rays, args.repeats)
    result["cornell"] = cornell
    result["cornell_lf_rays_per_s"] = cornell["lf_rays_per_s"]
    result["cornell_lf_vs_embree_1t"] = cornell["lf_rays_per_s"] / cornell["embree_1t_rays_per_s"]
    result["cornell_unresolved_share"] = cornell["hiz_unresolved_share"]
    result["hiz_vs_two_level_steps"] = cornell["steps_hiz"] / cornell["steps_two_level"]
    result["cornell_wavefront_rays_per_s"] = cornell["wavefront_rays_per_s"]
    result["wavefront_vs_reference_cornell"] = cornell["wavefront_vs_reference"]
    util = [cornell["wavefront_lane_utilisation"]]
    n_h = max(args.rays // 4, 500)
    steps = hierarchy_steps(load_scene("cornell_box"), (4, 4, 4), (128, 256), n_h)
    result["cornell_hierarchy_steps"] = steps
    for r in (128, 256):
        result[f"hiz_vs_two_level_steps_r{r}"] = steps[f"r{r}"]["hiz_vs_two_level_steps"]
    try:
        sponza_scene = load_scene("crytek_sponza")
    except SceneError as e:  # not on the scene path (it lives outside the repository) or unreadable
        result.update(dict.fromkeys(SPONZA_KEYS))
        result["sponza_note"] = f"crytek_sponza not loaded: {e}"
    else:
        sponza, sponza_lf = bench_scene(sponza_scene, (8, 4, 4), 64, args.rays, args.repeats)
        result["sponza"] = sponza
        frame = frame_shading(sponza_scene, sponza_lf, EmbreeCaster(sponza_scene), repeats=args.repeats)
        result["sponza_frame"] = frame
        result["sponza_frame_s"] = frame["frame_s"]
        del sponza_lf
        result["sponza_lf_rays_per_s"] = sponza["lf_rays_per_s"]
        result["sponza_lf_vs_embree_1t"] = sponza["lf_rays_per_s"] / sponza["embree_1t_rays_per_s"]
        result["sponza_hiz_vs_two_level_steps"] = sponza["steps_hiz"] / sponza["steps_two_level"]
        result["sponza_wavefront_rays_per_s"] = sponza["wavefront_rays_per_s"]
        result["wavefront_vs_reference_sponza"] = sponza["wavefront_vs_reference"]
        util.append(sponza["wavefront_lane_utilisation"])
        steps = hierarchy_steps(sponza_scene, (8, 4, 4), (128, 256), n_h)
        result["sponza_hierarchy_steps"] = steps
        for r in (128, 256):
            result[f"sponza_hiz_vs_two_level_steps_r{r}"] = steps[f"r{r}"]["hiz_vs_two_level_steps"]
        march = march_cost(sponza_scene, (8, 4, 4), (128, 512), args.rays, args.repeats)
        result["sponza_march_cost"] = march
        result["sponza_march_s_r512_over_r128"] = march["trace_s_ratio"]
        result["sponza_march_steps_r512_over_r128"] = march["steps_ratio"]
    result["lane_utilisation"] = min(util)
    ev = cornell_eval(load_scene("cornell_box"), quick=args.quick)
    result["cornell_eval"] = ev
    result["cornell_glossy_mse"] = ev["mse_glossy_indirect"]
    result["cornell_glossy_noise_floor"] = ev["noise_floor_glossy_indirect"]
    try:
        gpus = jax.devices("gpu")
    except RuntimeError:
        gpus = []
    result["gpu"] = gpu_figures(load_scene("cornell_box"), args.repeats) if gpus else None
    write_result("tracer", result)
    return result


if __name__ == "__main__":
    main()
