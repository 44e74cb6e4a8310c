"""``probeplace evaluate``: evaluate a probe set (ProbeSet JSON, baked first; or a baked .npz) on a view."""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np

from .._core import ConfigError


def add_parser(sub) -> None:
    """Register the ``evaluate`` subcommand on an argparse subparsers object."""
    from ..render import BACKEND_CHOICES
    from ..scene import add_scene_options

    e = sub.add_parser(
        "evaluate",
        help="evaluate a probe set on a scene view: MSE per component vs the path tracer (docs/evaluate.md)",
    )
    e.add_argument("--scene", required=True, help="scene name or file (see `probeplace scenes`)")
    add_scene_options(e)
    e.add_argument("--probes", required=True, help="ProbeSet .json (probeplace place) or baked .npz")
    e.add_argument("--view", default=None, help="camera name (default: the scene's first view)")
    e.add_argument("--out", default="results/eval", help="output folder (metrics.json is written last)")
    e.add_argument(
        "--shading",
        default="lightfield",
        choices=["lightfield", "irradiance", "sh"],
        help="diffuse shading from the probes",
    )
    e.add_argument("--width", type=int, default=128, help="image width, pixels")
    e.add_argument("--height", type=int, default=128, help="image height, pixels")
    e.add_argument("--spp", type=int, default=64, help="reference paths per pixel")
    e.add_argument("--glossy-spp", type=int, default=8, help="GGX directions per pixel (CRN)")
    e.add_argument(
        "--max-depth",
        type=int,
        default=8,
        help="camera path depth in segments; a bake from a ProbeSet traces max-depth − 1 "
        "(probes.bake_depth_for) and a baked .npz must have been baked so",
    )
    e.add_argument(
        "--hierarchy",
        default="hiz",
        choices=["hiz", "two_level", "flat"],
        help="light-field tracer's distance hierarchy",
    )
    e.add_argument("--seed", type=int, default=0, help="random seed of the bake and the renders")
    e.add_argument(
        "--radiance-res",
        type=int,
        default=None,
        help="bake: radiance map resolution (default: from the scene)",
    )
    e.add_argument("--bake-spp", type=int, default=16, help="bake: paths per texel ray")
    e.add_argument("--save-baked", default=None, help="bake: also save the baked probes to this .npz")
    e.add_argument(
        "--geometry-res",
        type=int,
        default=None,
        help="bake: geometry (distance, normal) map resolution (default: --radiance-res)",
    )
    e.add_argument(
        "--backend",
        default="jax",
        choices=BACKEND_CHOICES,
        help="path tracer of the bake and the references (mitsuba: Dr.Jit LLVM on the CPU, faster; auto: "
        "mitsuba on a CPU where it loads, else jax)",
    )
    e.set_defaults(func=run)


# EvalConfig / BakeConfig fields set from an option of the same name: their messages name the option.
_OPTIONS = (
    *("width", "height", "spp", "glossy_spp", "max_depth", "shading", "seed", "backend"),
    *("radiance_res", "geometry_res"),
)


def _as_option(e: ConfigError) -> ConfigError:
    """``EvalConfig.width must be ...`` as ``--width: EvalConfig.width must be ...`` (the option first)."""
    m = re.match(r"(?:EvalConfig|BakeConfig)\.(\w+)", str(e))
    if m is None or m.group(1) not in _OPTIONS:
        return e
    return ConfigError(f"--{m.group(1).replace('_', '-')}: {e}")


def check_eval_memory(config, what: str) -> None:
    """Refuse an evaluation whose reference render would not fit in memory, before anything is loaded
    (the renderer's own estimate, ``_core._checks.check_image_memory``)."""
    from .._core._checks import check_image_memory
    from ..render import COMPONENTS, RenderConfig

    check_image_memory(
        config.width,
        config.height,
        config.spp,
        components=len(COMPONENTS),
        paths_per_batch=RenderConfig.paths_per_batch,
        what=what,
    )


def _eval_config(args: argparse.Namespace):
    """The evaluation settings of the options, checked (messages name the option) and sized."""
    from ..probes._trace import TraceConfig
    from . import EvalConfig

    try:
        config = EvalConfig(
            width=args.width,
            height=args.height,
            spp=args.spp,
            glossy_spp=args.glossy_spp,
            max_depth=args.max_depth,
            shading=args.shading,
            trace=TraceConfig(hierarchy=args.hierarchy),
            seed=args.seed,
            progress=True,
            backend=args.backend,
        )
    except ConfigError as e:
        raise _as_option(e) from None
    check_eval_memory(config, "--width × --height: the reference render")
    return config


def _checked_outputs(args: argparse.Namespace, path: Path) -> None:
    """--save-baked and --out: the right kind of input, and writable, before any work."""
    from .._core._checks import check_writable_file, check_writable_folder
    from ._write import evaluation_bytes

    if args.save_baked is not None:
        if path.suffix != ".json":
            raise ConfigError(f"--save-baked saves a bake; {path} is already baked (give a ProbeSet .json)")
        if Path(args.save_baked).suffix != ".npz":
            raise ConfigError(f"--save-baked must name a .npz file, got {args.save_baked}")
        check_writable_file(args.save_baked, "--save-baked")
    check_writable_folder(args.out, "--out", size=evaluation_bytes(args.width, args.height))


def _checked_inputs(args: argparse.Namespace):
    """Every input checked before the scene is loaded and anything is baked or rendered: (path, config,
    bake config or None, ProbeSet or baked probes)."""
    from .._core import load_probe_set
    from .._core._checks import check_npz_archive
    from ..probes import BakeConfig, load_probes

    path = Path(args.probes)
    if path.suffix not in (".json", ".npz"):
        raise ConfigError(f"--probes must be a ProbeSet .json or a baked .npz, got {path}")
    config = _eval_config(args)  # first: the output's size bound needs a sensible image size
    _checked_outputs(args, path)
    if args.backend == "mitsuba":  # refuse before loading anything if its LLVM variant cannot load
        from ..render._mitsuba_backend import load_mitsuba

        try:
            load_mitsuba()
        except ImportError as e:
            raise ConfigError(f"--backend mitsuba: {e}") from None
    if path.suffix == ".npz":
        probes = load_probes(check_npz_archive(path, "--probes"))
        bake_cfg = None
    else:
        try:
            bake_cfg = BakeConfig(
                radiance_res=args.radiance_res, geometry_res=args.geometry_res, progress=True
            )
        except ConfigError as e:
            raise _as_option(e) from None
        if isinstance(args.bake_spp, bool) or args.bake_spp < 1:
            raise ConfigError(f"--bake-spp must be a positive integer, got {args.bake_spp}")
        probes, meta = load_probe_set(path)
        _check_recorded_scene(meta, path, args.scene)
    if not bool(np.asarray(probes.active).any()):
        raise ConfigError(f"--probes: {path} holds no active probes; nothing to bake or evaluate")
    return path, config, bake_cfg, probes


def _scene_key(name_or_path: str) -> str:
    """The name a scene loads under: a file's stem (``load_scene`` names a file scene so), else the name."""
    from ..scene import looks_like_path

    return Path(name_or_path).stem if looks_like_path(name_or_path) else str(name_or_path)


def _check_recorded_scene(meta: dict, path: Path, scene: str) -> None:
    """Refuse a ProbeSet file that records another scene (``probeplace place`` writes ``metadata.scene``:
    the name or path it was given) than ``--scene``, compared by the name each loads under; the check a
    baked ``.npz`` gets (``probes.check_bake_settings``), before the scene is even loaded."""
    from ..probes._bake import check_probe_scene

    record = meta.get("metadata")
    recorded = record.get("scene") if isinstance(record, dict) else None
    if not isinstance(recorded, str) or not recorded:
        return
    check_probe_scene(
        _scene_key(recorded),
        _scene_key(scene),
        made="placed",
        what=f"--probes: {path}: the probes",
        fix=f"evaluate them with --scene {recorded}, or place probes in {scene} (probeplace place {scene} "
        f"--out <file>); if both are the same scene under two names, delete metadata.scene from {path.name}",
    )


def _check_probes_fit(probes, path: Path, scene, args: argparse.Namespace, config, overrides, view) -> None:
    """After the scene is loaded, before any caster, bake or render: the probes lie in the scene (a baked
    file's recorded scene and depth first), the cameras are in free space, the lights reach the views."""
    from ..probes import check_bake_settings
    from ..probes._bake import check_probes_in_scene
    from ._scene_checks import check_views_and_lights

    if path.suffix == ".npz":
        check_bake_settings(probes, scene_name=scene.name, eval_max_depth=config.max_depth)
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    check_probes_in_scene(
        np.asarray(probes.pos_world)[np.asarray(probes.active)],
        lo,
        hi,
        f"--probes: {path}",
        scene=scene.name,
        fix=f"the probe set was made for another scene or in other units; place probes in {scene.name} "
        f"(probeplace place {args.scene} --out <file>) and evaluate those",
    )
    check_views_and_lights(scene, args.scene, overrides, view=view)


def run(args: argparse.Namespace) -> int:
    import jax

    from ..geometry import make_caster
    from ..probes import bake_depth_for, bake_probes, path_traced_radiance, save_probes
    from ..scene import load_scene, scene_overrides_from_args
    from . import evaluate, write_evaluation

    overrides = scene_overrides_from_args(args)  # a bad --sun/--sky/--camera fails before any work
    path, config, bake_cfg, probes = _checked_inputs(args)
    scene = load_scene(args.scene, overrides=overrides, require_light=True)
    views = [c.name for c in scene.views]
    if not views:
        raise ConfigError(f"scene {scene.name!r} has no view to evaluate (add one in its sidecar config)")
    view = args.view or views[0]
    if view not in views:
        raise ConfigError(f"--view: scene {scene.name!r} has no view {view!r}; views: {views}")
    _check_probes_fit(probes, path, scene, args, config, overrides, view)
    caster = make_caster(scene, use="render")
    if path.suffix == ".npz":
        lf = probes
    else:
        lf = bake_probes(
            scene,
            probes,
            caster=caster,
            radiance_fn=path_traced_radiance(
                scene,
                spp=args.bake_spp,
                max_depth=bake_depth_for(config.max_depth),
                caster=caster if args.backend == "jax" else None,
                backend=args.backend,
            ),
            key=jax.random.key(args.seed),
            config=bake_cfg,
        )
        if args.save_baked:
            save_probes(args.save_baked, lf)
    result = evaluate(scene, lf, view=view, config=config, caster=caster)
    paths = write_evaluation(result, args.out)
    m = result.metrics
    keys = ("mse_glossy_indirect", "noise_floor_glossy_indirect", "mse_diffuse_indirect", "mse_full")
    print(json.dumps({k: m[k] for k in keys} | {"unresolved_share": m["unresolved_share"]}))
    print(paths["metrics"])
    return 0
