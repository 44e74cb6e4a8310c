"""``probeplace evaluate``: evaluate a probe set (ProbeSet JSON, baked first; or a baked .npz) on a view.

The command is the experiment runner's bake and evaluation: every setting it does not name on its command
line is the runner's default (``ExperimentConfig()``'s ``bake``, ``tracer`` and ``eval`` groups, read
through ``experiment._schema.bake_values`` / ``eval_values``: one place for the defaults of both), the
random keys are split from ``--seed`` as the runner splits its run's seed, and the glossy rays run on the
wavefront light-field tracer (the runner's ``eval.trace_engine``).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import re
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import ClassVar

import numpy as np

from .._core import ConfigError, check_count, is_auto


def _count(text: str) -> int | str:
    """A count option's value: an int, or the text as given (``auto``; the config refuses other text in
    one line, naming the option)."""
    try:
        return int(text)
    except ValueError:
        return text


def add_parser(sub) -> None:
    """Register the ``evaluate`` subcommand on an argparse subparsers object."""
    from ..render import BACKEND_CHOICES
    from ._scene_options import add_scene_options

    e = sub.add_parser(
        "evaluate",  # its one-line help: cli._EVALUATE_HELP (the top-level help reads it unfilled)
        description="Every default is the experiment runner's (experiments/run.py, configs/): the same "
        "bake and evaluation as a run of it.",
    )
    e.add_argument("--scene", required=True, help="scene name or file (see `probeplace scenes`)")
    add_scene_options(e)
    from ..export import READABLE_SUFFIXES  # NumPy only

    engine_files = ", ".join(x for x in READABLE_SUFFIXES if x != ".json")
    e.add_argument(
        "--probes",
        required=True,
        help="ProbeSet .json (probeplace place), baked .npz, or a set exported to an engine file "
        f"({engine_files}, probeplace.ProbeExport .json: re-baked as placed there)",
    )
    e.add_argument("--view", default=None, help="camera name (default: the scene's first view)")
    e.add_argument("--out", default="results/eval", help="output folder (metrics.json is written last)")
    e.add_argument(
        "--shading",
        choices=["lightfield", "irradiance", "sh"],
        help="diffuse shading from the probes {runner}",
        action=_RunnerDefault,
    )
    e.add_argument("--width", type=int, help="image width, pixels {runner}", action=_RunnerDefault)
    e.add_argument("--height", type=int, help="image height, pixels {runner}", action=_RunnerDefault)
    _add_sample_options(e)
    e.add_argument(
        "--max-depth",
        type=int,
        help="camera path depth in segments; a bake from a ProbeSet traces max-depth − 1 "
        "(probes.bake_depth_for) and a baked .npz must have been baked so {runner}",
        action=_RunnerDefault,
    )
    e.add_argument(
        "--trace-engine",
        metavar="{wavefront,per_ray}",
        help="how the light-field tracer runs the glossy rays: wavefront (the same hits as per_ray, "
        "many times faster) or per_ray (vmapped nested loops) {runner}",
        action=_RunnerDefault,
    )
    e.add_argument(
        "--timing-repeats",
        type=int,
        help="shading runs timed (median) after the compile run {runner}",
        action=_RunnerDefault,
    )
    _add_trace_options(e)
    e.add_argument(
        "--seed", type=int, help="random seed of the bake and the renders {runner}", action=_RunnerDefault
    )
    _add_bake_options(e)
    e.add_argument(
        "--backend",
        choices=BACKEND_CHOICES,
        help="path tracer of the bake and the references (mitsuba: Dr.Jit LLVM on the CPU, faster; auto: "
        "mitsuba on a CPU where it loads, else jax) {runner}",
        action=_RunnerDefault,
    )
    e.set_defaults(func=run)


def _trace_fields() -> tuple:
    """The light-field tracer's settings the command takes: the fields of the runner's ``lightfield`` group
    (``experiment.LightFieldStage``: every ``probes.TraceConfig`` field but ``engine``, which is
    ``--trace-engine`` as the runner's ``eval.trace_engine``)."""
    import dataclasses

    from ..experiment import LightFieldStage

    return dataclasses.fields(LightFieldStage)


def _add_trace_options(e) -> None:
    """``--trace-<name>`` for each of :func:`_trace_fields`, its type the field's, its default the
    runner's (``--hierarchy`` is also ``--trace-hierarchy``'s older name)."""
    from ._options import flag, value_parser

    for f in _trace_fields():
        names = [flag(f.name, "trace_")] + (["--hierarchy"] if f.name == "hierarchy" else [])
        e.add_argument(
            *names,
            dest=f"trace_{f.name}",
            type=value_parser(f.type),
            metavar=f.name.upper(),
            help=f"light-field tracer: probes.TraceConfig.{f.name} (docs/tracer.md) {{runner}}",
            action=_RunnerDefault,
        )


def _add_sample_options(e) -> None:
    """The reference's sample counts (``auto``: chosen from a noise target, issue 33) and their target."""
    e.add_argument(
        "--spp",
        type=_count,
        help="reference paths per pixel, or auto: the fewest whose diffuse-indirect noise floor is at most "
        "--noise-target of the black image's MSE, from a pilot render {runner}",
        action=_RunnerDefault,
    )
    e.add_argument(
        "--glossy-spp", type=int, help="GGX directions per pixel (CRN) {runner}", action=_RunnerDefault
    )
    e.add_argument(
        "--glossy-ref-spp",
        type=_count,
        help="reference paths per GGX direction (CRN glossy reference, ≥ 2), or auto: chosen for "
        "--noise-target as --spp {runner}",
        action=_RunnerDefault,
    )
    e.add_argument(
        "--noise-target",
        type=float,
        help="an auto --spp / --glossy-ref-spp: the reference noise floor to reach, as a fraction of the "
        "black image's MSE {runner}",
        action=_RunnerDefault,
    )
    e.add_argument(
        "--max-spp",
        type=int,
        help="an auto --spp / --glossy-ref-spp: the most paths it may reach {runner}",
        action=_RunnerDefault,
    )


def _add_bake_options(e) -> None:
    """The bake's settings (a ProbeSet .json is baked first), its count and noise target among them."""
    e.add_argument(
        "--radiance-res", type=int, help="bake: radiance map resolution {runner}", action=_RunnerDefault
    )
    e.add_argument(
        "--bake-spp",
        type=_count,
        help="bake: paths per texel ray, or auto: chosen by a pilot for --bake-noise-target {runner}",
        action=_RunnerDefault,
    )
    e.add_argument(
        "--bake-noise-target",
        type=float,
        help="bake: an auto --bake-spp's relative noise of the radiance maps {runner}",
        action=_RunnerDefault,
    )
    e.add_argument(
        "--bake-max-spp",
        type=int,
        help="bake: the most paths per texel ray an auto --bake-spp may reach {runner}",
        action=_RunnerDefault,
    )
    e.add_argument("--save-baked", default=None, help="bake: also save the baked probes to this .npz")
    e.add_argument(
        "--geometry-res",
        type=int,
        help="bake: geometry (distance, normal) map resolution (default: --radiance-res)",
    )


# The options whose default is the runner's: option dest → where the runner keeps it (for messages).
RUNNER_KEYS = {
    "width": "eval.width",
    "height": "eval.height",
    "spp": "tracer.spp",
    "glossy_spp": "eval.glossy_spp",
    "glossy_ref_spp": "eval.glossy_ref_spp",
    "max_depth": "tracer.max_depth",
    "shading": "eval.shading",
    "timing_repeats": "eval.timing_repeats",
    "backend": "eval.backend",
    "seed": "seed",
    "radiance_res": "bake.radiance_res",
    "geometry_res": "bake.geometry_res",
    "bake_spp": "bake.spp",
    "noise_target": "tracer.noise_target",
    "max_spp": "tracer.max_spp",
    "bake_noise_target": "bake.noise_target",
    "bake_max_spp": "bake.max_spp",
    "trace_engine": "eval.trace_engine",
}


@functools.cache
def runner_keys() -> Mapping:
    """:data:`RUNNER_KEYS` and the light-field tracer's options (``trace_<name>`` → ``lightfield.<name>``,
    :func:`_trace_fields`). Read-only."""
    trace = {f"trace_{f.name}": f"lightfield.{f.name}" for f in _trace_fields()}
    return MappingProxyType(RUNNER_KEYS | trace)


@functools.cache  # fixed for the process; the options, the checks and --help all read it
def runner_defaults() -> Mapping:
    """The default of every option of :func:`runner_keys`, read from the runner's defaults
    (``ExperimentConfig()``: its ``bake``, ``tracer``, ``eval`` and ``lightfield`` groups). Read-only."""
    from ..experiment import ExperimentConfig, bake_values, eval_values

    cfg = ExperimentConfig()
    ev, bake = eval_values(cfg), bake_values(cfg)
    out = {k: ev[k] for k in RUNNER_KEYS if k in ev}
    out |= {f"trace_{f.name}": getattr(cfg.lightfield, f.name) for f in _trace_fields()}
    out |= {"radiance_res": bake["radiance_res"], "geometry_res": bake["geometry_res"]}
    out |= {"bake_noise_target": bake["noise_target"], "bake_max_spp": bake["max_spp"]}
    out |= {"bake_spp": cfg.bake.spp, "seed": cfg.seed, "trace_engine": cfg.eval.trace_engine}
    return MappingProxyType(out)


class _NotGiven:
    """The value of a runner-default option not on the command line."""

    def __repr__(self) -> str:
        return "the runner's"


NOT_GIVEN = _NotGiven()


class _RunnerDefault(argparse._StoreAction):
    """An option whose default is the runner's: parsed as :data:`NOT_GIVEN` when not given (``none`` may be
    a value given: ``--trace-edge-tol none``); its help's ``{runner}`` reads ``(default: 64, eval.width)``
    from the runner's defaults, only when ``--help`` prints it (the parser stays light to build)."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **{**kwargs, "default": NOT_GIVEN})

    @property
    def help(self) -> str:
        if "{runner}" not in self._help:
            return self._help
        value = runner_defaults()[self.dest]
        return self._help.replace("{runner}", f"(default: {value}, the runner's {runner_keys()[self.dest]})")

    @help.setter
    def help(self, text: str) -> None:
        self._help = text


def resolved_options(args: argparse.Namespace) -> dict:
    """The value of every option of :func:`runner_keys`: the command line's, else the runner's default."""
    given = {k: getattr(args, k, NOT_GIVEN) for k in runner_keys()}
    return {k: v if given[k] is NOT_GIVEN else given[k] for k, v in runner_defaults().items()}


def _as_option(e: ConfigError) -> ConfigError:
    """``EvalConfig.width must be ...`` as ``--width: EvalConfig.width must be ...`` (the option first):
    an EvalConfig / BakeConfig / TraceConfig field set from the option of the same name (:func:`runner_keys`;
    a ``BakeConfig`` field's option may be ``--bake-<name>``, a ``TraceConfig`` field's is
    ``--trace-<name>``)."""
    m = re.match(r"(EvalConfig|BakeConfig|TraceConfig)\.(\w+)", str(e))
    if m is None:
        return e
    kind, name = m.group(1, 2)
    if kind == "TraceConfig":
        name = f"trace_{name}"
    elif kind == "BakeConfig" and f"bake_{name}" in runner_keys():  # --bake-noise-target, not --noise-target
        name = f"bake_{name}"
    if name not in runner_keys():
        return e
    return ConfigError(f"--{name.replace('_', '-')}: {e}")


def eval_config(args: argparse.Namespace):
    """The evaluation settings: the runner's (``experiment._schema.eval_values`` of ``ExperimentConfig()``)
    with the options given over them, checked (messages name the option) and sized."""
    from ..evaluate import EvalConfig
    from ..experiment import ExperimentConfig, eval_values
    from ..probes import TraceConfig

    opt = resolved_options(args)
    values = eval_values(ExperimentConfig())
    values |= {k: opt[k] for k in values if k in opt}
    try:
        settings = {f.name: opt[f"trace_{f.name}"] for f in _trace_fields()}
        trace = TraceConfig(engine=opt["trace_engine"], **settings)
        config = EvalConfig(**values, trace=trace, seed=opt["seed"])
    except ConfigError as e:
        raise _as_option(e) from None
    from ..evaluate import check_eval_memory

    check_eval_memory(config, "--width × --height: the reference render")
    return config


def bake_config(args: argparse.Namespace):
    """The bake settings: the runner's (``experiment._schema.bake_values`` of ``ExperimentConfig()``) with
    ``--radiance-res`` / ``--geometry-res`` over them, checked (messages name the option)."""
    from ..experiment import ExperimentConfig, bake_values
    from ..probes import BakeConfig

    opt = resolved_options(args)
    values = bake_values(ExperimentConfig())
    values |= {"radiance_res": opt["radiance_res"], "geometry_res": opt["geometry_res"]}
    values |= {"noise_target": opt["bake_noise_target"], "max_spp": opt["bake_max_spp"]}
    try:
        return BakeConfig(**values)
    except ConfigError as e:
        raise _as_option(e) from None


def _checked_outputs(args: argparse.Namespace, path: Path, config) -> None:
    """--save-baked and --out: the right kind of input, and writable, before any work."""
    from .._core.runtime import check_writable_file, check_writable_folder
    from ..evaluate import evaluation_bytes

    if args.save_baked is not None:
        if path.suffix != ".json":
            raise ConfigError(f"--save-baked saves a bake; {path} is already baked (give a ProbeSet .json)")
        if Path(args.save_baked).suffix != ".npz":
            raise ConfigError(f"--save-baked must name a .npz file, got {args.save_baked}")
        check_writable_file(args.save_baked, "--save-baked")
    check_writable_folder(args.out, "--out", size=evaluation_bytes(config.width, config.height))


def _checked_inputs(args: argparse.Namespace):
    """Every input checked before the scene is loaded and anything is baked or rendered: (path, config,
    bake config or None, ProbeSet or baked probes)."""
    from .._core.runtime import check_npz_archive
    from ..probes import load_probes

    path = Path(args.probes)
    # exported sets too (export.read_probes; issue 36: a set edited in an engine is scored again; positions
    # in scene units, in probeplace's frame)
    from ..export import READABLE_SUFFIXES

    exported = [x for x in READABLE_SUFFIXES if x != ".json"]
    if path.suffix not in (".json", ".npz", *exported):
        raise ConfigError(
            f"--probes must be a ProbeSet .json, a baked .npz or an exported set "
            f"({', '.join(exported)}, probeplace.ProbeExport .json), got {path}"
        )
    config = eval_config(args)  # first: the output's size bound needs a sensible image size
    _checked_outputs(args, path, config)
    from ..pipeline import check_backend

    check_backend(config.backend, "--backend mitsuba")  # before loading anything
    if path.suffix == ".npz":
        probes = load_probes(check_npz_archive(path, "--probes"))
        bake_cfg = None
    else:
        bake_cfg = bake_config(args)
        check_count(resolved_options(args)["bake_spp"], "--bake-spp")
        probes, meta = _placed_probes(path)
        _check_recorded_scene(meta, path, args.scene)
    if not bool(np.asarray(probes.active).any()):
        raise ConfigError(f"--probes: {path} holds no active probes; nothing to bake or evaluate")
    return path, config, bake_cfg, probes


def _placed_probes(path: Path):
    """(ProbeSet, its record: method, units_m, metadata) of a ProbeSet .json or of an exported set, read
    once by ``export.read_probes`` (glTF, USD, Three.V8, probeplace.ProbeExport JSON): method, units and
    metadata (the scene it was placed in) come along."""
    import jax.numpy as jnp

    from .._core import ProbeSet
    from ..export import ExportError, read_probes

    try:
        exp = read_probes(path)
    except ExportError as e:
        raise ConfigError(f"--probes: {e}") from None
    probes = ProbeSet(
        pos_world=jnp.asarray(exp.positions, jnp.float32), active=jnp.asarray(exp.active), method=exp.method
    )
    return probes, {"method": exp.method, "units_m": exp.units_m, "metadata": exp.metadata}


def _scene_key(name_or_path: str) -> str:
    """The name a scene loads under: a file's stem (``load_scene`` names a file scene so), else the name."""
    from ..scene import looks_like_path

    return Path(name_or_path).stem if looks_like_path(name_or_path) else str(name_or_path)


def _check_recorded_scene(meta: dict, path: Path, scene: str) -> None:
    """Refuse a ProbeSet file that records another scene (``probeplace place`` writes ``metadata.scene``:
    the name or path it was given) than ``--scene``, compared by the name each loads under; the check a
    baked ``.npz`` gets (``probes.check_bake_settings``), before the scene is even loaded."""
    from ..probes import check_probe_scene

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
    from ..evaluate import check_views_and_lights
    from ..probes import check_bake_settings, check_probes_in_scene

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


class _Stages:
    """One line on stderr as each stage starts (``probeplace evaluate: [  12.3 s] bake: ...``), the seconds
    since the command started first; none with ``--quiet`` (``_core.runtime._progress.set_progress``)."""

    _EVAL: ClassVar[dict[str, str]] = {
        "reference": "reference render: {w}×{h} pixels, {spp} paths per pixel",
        "primary": "primary hits and GGX samples: {gspp} per pixel",
        "crn": "glossy reference (CRN): {gref} paths per GGX direction",
        "shading": "probe shading ({engine} tracer): 1 compile run + {rep} timed",
        "perfect_trace": "perfect trace of the glossy rays",
        "score": "scoring",
    }

    def __init__(self, config) -> None:
        from .._core.runtime import _progress

        self.on = _progress._enabled
        self.t0 = time.perf_counter()
        auto = f"auto (noise target {config.noise_target:g}, pilot {config.pilot_spp})"
        self.fields = {
            "w": config.width,
            "h": config.height,
            "spp": auto if is_auto(config.spp) else config.spp,
            "gspp": config.glossy_spp,
            "gref": auto if is_auto(config.glossy_ref_spp) else config.glossy_ref_spp,
            "engine": config.trace.engine,
            "rep": config.timing_repeats,
        }

    def __call__(self, text: str) -> None:
        if self.on:
            text = self._EVAL[text].format(**self.fields) if text in self._EVAL else text
            print(f"probeplace evaluate: [{time.perf_counter() - self.t0:7.1f} s] {text}", file=sys.stderr)
            sys.stderr.flush()


def run(args: argparse.Namespace) -> int:
    import jax

    from ..evaluate import evaluate, write_evaluation
    from ..geometry import make_caster
    from ..pipeline import bake, check_view
    from ..probes import save_probes
    from ..scene import load_scene
    from ._scene_options import scene_overrides_from_args

    overrides = scene_overrides_from_args(args)  # a bad --sun/--sky/--camera fails before any work
    path, config, bake_cfg, probes = _checked_inputs(args)
    say = _Stages(config)  # its first line after the last refusal: a refusal stays one line
    scene = load_scene(args.scene, overrides=overrides, require_light=True)
    view = check_view(scene, args.view, "--view")
    _check_probes_fit(probes, path, scene, args, config, overrides, view)
    say(f"scene {scene.name} loaded and checked; building the ray caster")
    caster = make_caster(scene, use="render")
    opt = resolved_options(args)
    # the runner's keys: the bake's and the evaluation's split from the seed (experiment._run._execute)
    k_bake, k_eval = jax.random.split(jax.random.key(opt["seed"]))
    samples = None
    if path.suffix == ".npz":
        lf = probes
    else:
        backend = config.backend  # --backend (or the runner's) for the bake too
        n = int(np.asarray(probes.active).sum())
        res, spp = bake_cfg.radiance_res, opt["bake_spp"]
        say(f"bake: {n} probes, {res}² radiance maps, {spp} paths per texel ray ({backend})")
        baked = bake(  # padded as the runner's (bake.pad_pow2): a few probe counts, compiled once each
            scene,
            probes,
            config=bake_cfg,
            spp=spp,
            eval_max_depth=config.max_depth,
            backend=backend,
            caster=caster,
            key=k_bake,
            say=say,
        )
        lf, samples = baked.probes, baked.samples
        if args.save_baked:
            say(f"writing {args.save_baked}")
            save_probes(args.save_baked, lf)
    result = evaluate(scene, lf, view=view, config=config, caster=caster, key=k_eval, stage=say)
    if samples is not None:  # how the bake's paths were chosen, beside the reference's ``samples``
        result = dataclasses.replace(result, metrics={**result.metrics, "bake_samples": samples.to_dict()})
    say(f"writing {args.out}")
    paths = write_evaluation(result, args.out)
    m = result.metrics
    keys = ("mse_glossy_indirect", "noise_floor_glossy_indirect", "mse_diffuse_indirect", "mse_full")
    print(json.dumps({k: m[k] for k in keys} | {"unresolved_share": m["unresolved_share"]}))
    print(paths["metrics"])
    return 0
