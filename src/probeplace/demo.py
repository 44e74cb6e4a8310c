"""``make demo``: the furthest-reaching real thing the project can do on the built-in Cornell box.

Until the experiment runner exists (issue 7) this runs the stages that are built, end to end, and
writes what each produced into one results folder. The folder is written atomically: everything goes
into a hidden sibling ``.<name>.partial`` that is renamed into place only when every stage finished, so
an interrupted run never leaves a folder that looks complete.
"""

from __future__ import annotations

import json
import shutil
import time
from collections.abc import Callable
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from ._core import RunFiles, Scene, load_pyplot
from ._core.runtime import progress_bar

DEMO_WIDTH = 128
DEMO_HEIGHT = 128


def _primary_rays(scene: Scene, view: str, width: int, height: int) -> tuple[jax.Array, jax.Array]:
    from .render import camera_rays

    n = width * height
    pixels = jnp.arange(n, dtype=jnp.int32)
    centre = jnp.full((n, 2), 0.5, jnp.float32)
    return camera_rays(scene.view(view), width, height, pixels, centre)


def _stage_gbuffer(scene: Scene, grid, out: Path) -> dict:
    """Exact primary hits and sphere-traced SDF hits for every view; images and their agreement."""
    plt = load_pyplot()

    from .geometry import make_caster, trace_sdf_rays

    caster = make_caster(scene)
    h_vox = float(grid.voxel_size)
    stats = {"caster": type(caster).__name__}
    for view in [c.name for c in scene.views]:
        o, d = _primary_rays(scene, view, DEMO_WIDTH, DEMO_HEIGHT)
        hit = caster.closest_hit(o, d)
        t_sdf, ok_sdf = trace_sdf_rays(grid, o, d, jnp.float32(1e4))
        t_exact = np.asarray(hit.t)
        valid = np.isfinite(t_exact) & np.asarray(ok_sdf)
        err = np.abs(np.asarray(t_sdf)[valid] - t_exact[valid])
        stats[view] = {
            "pixels": DEMO_WIDTH * DEMO_HEIGHT,
            "exact_hits": int(np.isfinite(t_exact).sum()),
            "sdf_hits": int(np.asarray(ok_sdf).sum()),
            "sdf_within_one_voxel": float((err <= h_vox).mean()) if err.size else 0.0,
            "sdf_median_abs_error_voxels": float(np.median(err) / h_vox) if err.size else None,
        }
        shape = (DEMO_HEIGHT, DEMO_WIDTH)
        normal = np.asarray(hit.shading_normal).reshape(*shape, 3) * 0.5 + 0.5
        depth = np.where(np.isfinite(t_exact), t_exact, np.nan).reshape(shape)
        depth_sdf = np.where(np.asarray(ok_sdf), np.asarray(t_sdf), np.nan).reshape(shape)
        albedo = np.asarray(scene.materials.base_color)[np.maximum(np.asarray(hit.material), 0)]
        albedo = np.where(np.isfinite(t_exact)[:, None], albedo, 0.0).reshape(*shape, 3)
        fig, ax = plt.subplots(1, 4, figsize=(13, 3.6), constrained_layout=True)
        ax[0].imshow(albedo)
        ax[0].set_title("base colour (exact hit)")
        ax[1].imshow(np.clip(normal, 0, 1))
        ax[1].set_title("shading normal")
        vmax = np.nanmax(depth)
        im = ax[2].imshow(depth, vmin=0, vmax=vmax, cmap="viridis")
        ax[2].set_title("exact distance")
        fig.colorbar(im, ax=ax[2], shrink=0.8)
        im = ax[3].imshow((depth_sdf - depth) / h_vox, cmap="coolwarm", vmin=-2, vmax=2)
        ax[3].set_title("SDF trace − exact (voxels)")
        fig.colorbar(im, ax=ax[3], shrink=0.8)
        for a in ax:
            a.set_axis_off()
        fig.suptitle(f"{scene.name} — view '{view}'")
        fig.savefig(out / f"gbuffer_{view}.png", dpi=110)
        plt.close(fig)
    return stats


def _stage_sdf_slice(scene: Scene, grid, samples, out: Path) -> dict:
    """A slice of the SDF through the middle of the box, with the surface samples near the slice."""
    plt = load_pyplot()

    values = np.asarray(grid.values)
    k = values.shape[2] // 2
    z = float(grid.origin[2]) + k * float(grid.voxel_size)
    sl = values[:, :, k].T
    lo = np.asarray(grid.origin)
    hi = lo + (np.array(values.shape) - 1) * float(grid.voxel_size)
    fig, ax = plt.subplots(figsize=(6, 5.4), constrained_layout=True)
    lim = np.abs(sl).max()
    im = ax.imshow(sl, origin="lower", extent=(lo[0], hi[0], lo[1], hi[1]), cmap="RdBu", vmin=-lim, vmax=lim)
    ax.contour(sl, levels=[0.0], colors="k", linewidths=0.8, extent=(lo[0], hi[0], lo[1], hi[1]))
    p = np.asarray(samples.position)
    near = np.abs(p[:, 2] - z) < 2 * float(grid.voxel_size)
    ax.scatter(p[near, 0], p[near, 1], s=3, c="gold", label="surface samples (±2 voxels)")
    ax.legend(loc="upper right", fontsize=8)
    fig.colorbar(im, ax=ax, label="signed distance (scene units)")
    ax.set_title(f"SDF slice z = {z:.3g} (zero level in black)")
    fig.savefig(out / "sdf_slice.png", dpi=110)
    plt.close(fig)
    return {"slice_z": z, "samples_near_slice": int(near.sum())}


def _stage_reference(scene: Scene, cfg: dict, out: Path) -> dict:
    """Path-traced reference of the front view: EXR with every component and its variance, and a PNG."""
    from .render import RenderConfig, render, save_render

    rc = RenderConfig(width=cfg["width"], height=cfg["height"], spp=cfg["spp"], max_depth=cfg["max_depth"])
    t0 = time.perf_counter()
    result = render(scene, cfg["view"], rc, key=jax.random.key(cfg["seed"]))
    seconds = time.perf_counter() - t0
    exr, png = save_render(result, out / f"reference_{cfg['view']}")
    full = np.asarray(result.image("full"))
    var = np.asarray(result.variance("full"))
    return {
        "view": cfg["view"],
        "size": [cfg["width"], cfg["height"]],
        "spp": cfg["spp"],
        "max_depth": cfg["max_depth"],
        "samples_per_s": cfg["width"] * cfg["height"] * cfg["spp"] / seconds,
        "mean_radiance": float(full.mean()),
        "noise_floor_rel": float(var.mean() / max(float((full**2).mean()), 1e-30)),
        "files": [exr.name, png.name],
    }


def _stage_place(scene: Scene, cfg: dict, out: Path) -> tuple[dict, object]:
    """Automatic placement (fewest probes reaching full coverage), saved as a ProbeSet file + top view."""
    from .pipeline import write_placement
    from .placement import place

    placed = place(scene, method=cfg["method"], budget="auto", seed=cfg["seed"])
    probes, meta = placed.probes, placed.metadata
    pos = np.asarray(probes.pos_world)[np.asarray(probes.active)]
    write_placement(  # probes.json, its coverage detail and the top view
        scene,
        placed,
        out / RunFiles.probes,
        png=out / "probes_top_view.png",
        title=f"{scene.name}: {len(pos)} probes (auto)",
        metadata=meta,
    )
    summary = {k: meta[k] for k in ("coverage", "n_probes", "timings") if k in meta}
    summary["n_active"] = len(pos)
    return summary, probes


def _stage_bake(scene: Scene, probes, cfg: dict, out: Path) -> dict:
    """Bake the placed probes with the reference path tracer; npz, contact sheet and a glTF export."""
    from .pipeline import bake, export_baked
    from .probes import DEFAULT_EVAL_MAX_DEPTH, BakeConfig, save_contact_sheet, save_probes
    from .render import default_caster

    caster = default_caster(scene)
    t0 = time.perf_counter()
    lf = bake(
        scene,
        probes,
        config=BakeConfig(radiance_res=cfg["radiance_res"], probes_per_batch=2),
        spp=cfg["spp"],
        eval_max_depth=DEFAULT_EVAL_MAX_DEPTH,
        backend="jax",
        caster=caster,
        key=jax.random.key(cfg["seed"]),
        pad=False,
    ).probes
    seconds = time.perf_counter() - t0
    save_probes(out / RunFiles.baked, lf)
    save_contact_sheet(lf, out / "probes_contact_sheet.png")
    gltf = export_baked(out / RunFiles.baked, ["gltf"], out)
    return {
        "radiance_res": lf.radiance_res,
        "probes": int(lf.pos_world.shape[0]),
        "inside_geometry": int(np.asarray(lf.inside).sum()),
        "seconds": round(seconds, 2),
        "exported": [Path(p).name for p in gltf],
    }


DEFAULT_CONFIG = {
    "scene": "cornell_box",
    "reference": {"view": "front", "width": 128, "height": 128, "spp": 64, "max_depth": 8, "seed": 0},
    "place": {"method": "skeleton+medial", "seed": 0},
    "bake": {"radiance_res": 32, "spp": 8, "seed": 1},
}


def _merge_config(config: dict) -> dict:
    """DEFAULT_CONFIG overridden by ``config``; unknown keys are a ConfigError naming them."""
    from ._core import ConfigError

    cfg = {k: dict(v) if isinstance(v, dict) else v for k, v in DEFAULT_CONFIG.items()}
    for key, value in config.items():
        if key not in cfg:
            raise ConfigError(f"demo config: unknown key {key!r}; known: {sorted(cfg)}")
        if isinstance(cfg[key], dict):
            if not isinstance(value, dict):
                raise ConfigError(f"demo config: {key!r} must be a mapping, got {value!r}")
            unknown = set(value) - set(DEFAULT_CONFIG[key])
            if unknown:
                raise ConfigError(f"demo config: unknown keys {sorted(unknown)} in {key!r}")
            cfg[key].update(value)
        else:
            cfg[key] = value
    return cfg


def load_demo_config(path: str | Path) -> dict:
    """Read a demo YAML config (configs/demo.yaml): the overrides :func:`run_demo` merges into
    DEFAULT_CONFIG (and checks there). A clear ConfigError for a missing or broken file."""
    import yaml

    from ._core import ConfigError

    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"config file not found: {path}")
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as e:
        raise ConfigError(f"{path}: not valid YAML ({e})") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: the top level must be a mapping")
    return data


def run_demo(out_dir: str | Path = "results/demo", config: dict | None = None) -> int:
    """Run every built stage on the Cornell box; print what was written. Returns the exit code."""
    from .geometry import build_sdf, sample_surface
    from .scene import load_scene

    cfg = _merge_config(config or {})
    out = Path(out_dir)
    partial = out.parent / f".{out.name}.partial"
    if partial.exists():
        shutil.rmtree(partial)
    partial.mkdir(parents=True)

    summary: dict = {"scene": cfg["scene"], "device": jax.devices()[0].platform, "config": cfg, "stages": {}}
    state: dict = {}

    def load():
        state["scene"] = scene = load_scene(cfg["scene"])
        return {
            "triangles": scene.n_triangles,
            "views": [c.name for c in scene.views],
            "unit_m": scene.unit_m,
        }

    def sdf():
        state["grid"] = g = build_sdf(state["scene"], cache_dir=False)
        return {"voxel_size": float(g.voxel_size), "shape": list(g.shape)}

    def samples():
        state["samples"] = s = sample_surface(state["scene"], key=jax.random.key(0))
        return {"n_samples": s.n, "total_area": float(jnp.sum(s.area))}

    def placed():
        result, state["probes"] = _stage_place(state["scene"], cfg["place"], partial)
        return result

    stages: list[tuple[str, Callable[[], dict]]] = [
        ("load scene", load),
        ("build SDF", sdf),
        ("surface samples", samples),
        (
            "G-buffer: exact ray cast vs SDF trace",
            lambda: _stage_gbuffer(state["scene"], state["grid"], partial),
        ),
        (
            "SDF slice figure",
            lambda: _stage_sdf_slice(state["scene"], state["grid"], state["samples"], partial),
        ),
        ("path-traced reference", lambda: _stage_reference(state["scene"], cfg["reference"], partial)),
        ("automatic placement", placed),
        ("bake + export", lambda: _stage_bake(state["scene"], state["probes"], cfg["bake"], partial)),
    ]
    for name, fn in progress_bar(stages, desc="demo", unit="stage"):
        t0 = time.perf_counter()
        result = fn()
        result["seconds"] = round(time.perf_counter() - t0, 3)
        summary["stages"][name] = result

    (partial / "summary.json").write_text(json.dumps(summary, indent=2, default=str))
    if out.exists():
        shutil.rmtree(out)
    partial.rename(out)
    print(f"probeplace demo: wrote {out}/")
    for f in sorted(out.iterdir()):
        print(f"  {f.name:<32} {f.stat().st_size / 1024:8.1f} KiB")
    return 0
