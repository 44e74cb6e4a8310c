"""``run(cfg) -> RunResult``: one experiment run, end to end, into an atomically written results folder.

Stages: load the scene (optionally offset/rotated) → place (timed) → bake (timed, progress bar) →
evaluate (when ``probeplace.evaluate`` provides it) → export (optional) → write ``config.yaml``,
``metrics.json``, ``env.json``, the probe set and its ``probes.coverage.npz``, the baked probes, images
and ``DONE``.

**Timings** (``metrics.json`` ``timings``, seconds). Every timed stage ``X`` of ``place``, ``bake`` and
``eval`` has ``X_s`` (wall time of the stage), ``X_compile_s`` (the part spent compiling, see
:func:`_timed`) and ``X_run_s = X_s − X_compile_s``; ``place_bake_s`` is ``place_s + bake_s`` and
``place_bake_run_s`` is ``place_run_s + bake_run_s``. All runs of a sweep in one process share compiled
code, so the first run pays nearly all the compilation (issue 17: a grid's 61.7 s bake against 7.6 s for
the next method in the same sweep); the ``_run_s`` figures are what the report compares methods by.
``scene_s`` is the scene load (no split).
"""

from __future__ import annotations

import contextlib
import json
import logging
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._core import ConfigError, ProbeplaceError, RunFiles
from . import _results
from ._inputs import NOT_COMPARED, RECORD_ONLY, json_digest, run_inputs
from ._schema import (
    ExperimentConfig,
    bake_config,
    config_to_dict,
    config_to_yaml,
    eval_config,
    load_config_yaml,
    place_values,
    to_config,
)

log = logging.getLogger(__name__)

#: Beside ``probes.json``: each probe's part in the coverage and the uncovered samples (docs/view.md).


class EvaluationUnavailable(ProbeplaceError):
    """``eval.enabled`` is set but ``probeplace.evaluate`` does not provide ``evaluate`` yet."""


@dataclass(frozen=True)
class RunResult:
    """What :func:`run` did.

    Attributes:
        out_dir: the finished run folder.
        metrics: the contents of ``metrics.json``.
        skipped: True when the folder was already complete and nothing was run.
    """

    out_dir: Path
    metrics: dict
    skipped: bool = False


def run_name(cfg: ExperimentConfig) -> str:
    """The run folder name: ``cfg.run`` or
    scene[~offset]__method[+refiner]__b<budget or m<memory>>__s<seed>[__clearance=..][__region=..]
    [__o<placer options>]."""
    if cfg.run:
        return cfg.run
    scene = Path(cfg.scene.name).stem
    t = cfg.scene.translate_frac
    if any(float(x) != 0.0 for x in t) or float(cfg.scene.rotate_deg) != 0.0:
        scene += "~t" + ",".join(f"{float(x):g}" for x in t) + f"~r{float(cfg.scene.rotate_deg):g}"
    method = cfg.placer.method + ("" if cfg.refiner.name == "none" else f"+{cfg.refiner.name}")
    budget = cfg.placer.budget if cfg.placer.memory_budget is None else f"m{cfg.placer.memory_budget}"
    name = f"{scene}__{method}__b{str(budget).replace(' ', '')}__s{cfg.seed}"
    for key in ("clearance", "region"):  # each value gets its own run folder, as the options below
        if getattr(cfg.placer, key) is not None:
            name += f"__{key}={_option_text(getattr(cfg.placer, key))}"
    if cfg.placer.objective != "coverage":  # the refiner's objective (the default keeps older names)
        name += f"__objective={cfg.placer.objective}"
    if cfg.placer.options:  # e.g. a swept grid offset: each value gets its own run folder
        name += "__o" + ",".join(f"{k}={_option_text(v)}" for k, v in sorted(cfg.placer.options.items()))
    if cfg.scene.overrides:  # a swept sun or sky too; a hash: cameras would make the name too long
        name += "__scene=" + json_digest(cfg.scene.overrides)[:8]
    return name


def _option_text(value) -> str:
    """A placer option as folder-name text: sequences joined by ``_``, numbers in ``%g``, mappings as
    ``key-value`` pairs."""
    if isinstance(value, dict):
        return "_".join(f"{k}-{_option_text(v)}" for k, v in sorted(value.items()))
    if not isinstance(value, str) and hasattr(value, "__iter__"):  # list, tuple, OmegaConf ListConfig
        return "_".join(_option_text(v) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


def run_dir(cfg: ExperimentConfig) -> Path:
    """``results_dir/name/<run name>``."""
    return Path(cfg.results_dir) / cfg.name / run_name(cfg)


def _load_unmoved(scene_cfg, require_light: bool) -> Any:
    from ..scene import load_scene

    overrides = dict(getattr(scene_cfg, "overrides", None) or {}) or None
    return load_scene(scene_cfg.name, overrides=overrides, require_light=require_light)


def load_experiment_scene(scene_cfg, *, with_translation: bool = False, require_light: bool = False) -> Any:
    """The configured scene (its sidecar and ``overrides`` applied), moved by ``translate_frac`` × extent
    and rotated about +Y through its centre; with ``with_translation``, also the translation (scene units)
    as a float64 3-vector. ``require_light``: refuse a scene with no light (``load_scene``'s)."""
    from .._core import scene_box
    from ..scene import axis_angle_rotation, transform_scene

    scene = _load_unmoved(scene_cfg, require_light)
    t = np.asarray(scene_cfg.translate_frac, np.float64)
    deg = float(scene_cfg.rotate_deg)
    lo, hi = scene_box(scene)
    if not t.any() and deg == 0.0:
        return (scene, np.zeros(3)) if with_translation else scene
    centre = 0.5 * (lo + hi)
    rot = np.asarray(axis_angle_rotation([0.0, 1.0, 0.0], np.deg2rad(deg)), np.float64)
    # x ↦ R (x − c) + c + t·extent
    translation = centre - rot @ centre + t * (hi - lo)
    moved = transform_scene(scene, rotation=rot, translation=translation)
    return (moved, t * (hi - lo)) if with_translation else moved


def _placer_options(cfg: ExperimentConfig, translation: np.ndarray) -> dict:
    """``placer.options``, plus, for the lattice methods (grid, lod-grid, Vardis's dense grid) of a translated
    scene, ``shift = −translation``: those lattices are anchored to the scene's bounding box and would move
    with the scene, so the shift keeps them where they were in the world and the scene really moves
    *relative to the grid* (the stability study). The skeleton methods' SDF lattice moves with the scene."""
    from ..placement import get_method

    opts = dict(cfg.placer.options or {})
    if get_method(cfg.placer.method).lattice and np.any(translation):
        base = np.broadcast_to(np.asarray(opts.get("shift", (0.0, 0.0, 0.0)), np.float64), (3,))
        opts["shift"] = (base - translation).tolist()
    return opts


# JAX's compile phases, recorded with their start and end through jax.monitoring (jax/_src/dispatch.py:
# JAXPR_TRACE_EVENT, JAXPR_TO_MLIR_MODULE_EVENT, BACKEND_COMPILE_EVENT; the backend phase includes a
# persistent-cache lookup).
_JAX_COMPILE_EVENTS = frozenset(
    (
        "/jax/core/compile/jaxpr_trace_duration",
        "/jax/core/compile/jaxpr_to_mlir_module_duration",
        "/jax/core/compile/backend_compile_duration",
    )
)


def _covered_s(spans: list[tuple[float, float]], lo: float, hi: float) -> float:
    """Seconds of [lo, hi] covered by the union of ``spans`` (a nested jit's trace lies inside its
    caller's: counted once)."""
    total, end = 0.0, lo
    for s, e in sorted(spans):
        s, e = max(s, end), min(e, hi)
        if e > s:
            total += e - s
            end = e
    return total


@contextlib.contextmanager
def _timed(timings: dict, stage: str, *, drjit: bool = False) -> Iterator[None]:
    """Time the ``with`` block into ``timings``: ``<stage>_s`` (wall), ``<stage>_compile_s`` and
    ``<stage>_run_s`` (wall minus compile; both ≥ 0, summing to the wall time). The block must wait for
    its results (``jax.block_until_ready``), as the wall time always did.

    Compile time is *measured*, not inferred from a first-vs-later batch difference: JAX reports each
    trace, lowering and XLA compilation with its start and end (``jax.monitoring`` time spans), and the
    union of those spans inside the block is the compile time — every jitted function of the stage
    (caster, path tracer, filters, the inside test), a single-op dispatch of new shapes included, each
    counted once however nested. An executable already in memory (same shapes as an earlier run of the
    process) costs nothing here; a persistent-cache hit still counts its tracing, lowering and lookup.
    With ``drjit`` (a Mitsuba backend in the block) Dr.Jit's kernel history adds the code generation and
    LLVM compilation of the kernels it had not cached (``cache_hit == 0``); Dr.Jit re-traces the Python
    of its kernels on every call, so that tracing and the cache lookup are run time, as they would be in
    any later run.
    """
    import jax

    spans: list[tuple[float, float]] = []

    def listen(event: str, start: float, end: float, **_) -> None:
        if event in _JAX_COMPILE_EVENTS:
            spans.append((start, end))

    dr, had_history = None, False
    if drjit:
        import drjit as dr

        had_history = dr.flag(dr.JitFlag.KernelHistory)
        dr.set_flag(dr.JitFlag.KernelHistory, True)
        dr.kernel_history()  # reading it clears it: only this block's kernels are counted
    jax.monitoring.register_event_time_span_listener(listen)
    lo, t0 = time.time(), time.perf_counter()  # jax.monitoring stamps spans with time.time()
    try:
        yield
    finally:
        wall, hi = time.perf_counter() - t0, time.time()
        jax.monitoring.unregister_event_time_span_listener(listen)
        compile_s = _covered_s(spans, lo, hi)
        if dr is not None:
            kernels = dr.kernel_history()
            dr.set_flag(dr.JitFlag.KernelHistory, had_history)
            ms = sum(
                k.get("codegen_time", 0.0) + k.get("backend_time", 0.0)
                for k in kernels
                if k.get("cache_hit") == 0
            )
            compile_s += 1e-3 * ms  # Dr.Jit reports milliseconds
        compile_s = min(compile_s, wall)  # two clocks: never more than the wall time
    timings[f"{stage}_s"] = wall
    timings[f"{stage}_compile_s"] = compile_s
    timings[f"{stage}_run_s"] = wall - compile_s


def _check_backends(cfg: ExperimentConfig) -> None:
    """Refuse ``mitsuba`` backends whose Mitsuba module or LLVM variant cannot load, before any work
    (``pipeline.check_backend``, as ``probeplace evaluate --backend mitsuba``)."""
    from ..pipeline import check_backend

    for key, used, backend in (
        ("bake.backend", cfg.bake.enabled, cfg.bake.backend),
        ("eval.backend", cfg.eval.enabled, cfg.eval.backend),
    ):
        if used:
            check_backend(backend, key)


def _tree_nbytes(tree) -> int:
    import jax

    return int(sum(np.asarray(x).nbytes for x in jax.tree_util.tree_leaves(tree) if hasattr(x, "shape")))


def _evaluate(scene, lf, cfg: ExperimentConfig, caster, key, out: Path) -> dict:
    """``probeplace.evaluate`` with the run's evaluation settings; writes ``eval/``, returns its metrics."""
    from ..evaluate import evaluate, write_evaluation

    config = eval_config(cfg)
    result = evaluate(scene, lf, view=cfg.eval.view, config=config, caster=caster, key=key)
    write_evaluation(result, out / RunFiles.eval_dir)
    metrics = dict(result.metrics)
    metrics.setdefault("backend", config.backend)  # who rendered the reference
    return metrics


def run(cfg: Any, *, force: bool = False) -> RunResult:
    """Run one experiment; a finished run folder is kept and returned as ``skipped`` when it ran with the
    same config and inputs (``inputs.json``: scene file hash, resolved sidecar, code version; ``_inputs``),
    refused when they differ or were not recorded, redone with ``redo=stale`` or ``force``.

    Args:
        cfg: an :class:`ExperimentConfig`, a dict or an OmegaConf node (Hydra's ``cfg``).
        force: redo a finished run whatever it ran with (``redo=all``).

    Returns:
        :class:`RunResult` with the run folder and its metrics (``timings``: wall, compile and run seconds
        per stage, module docstring).

    Raises:
        ConfigError: invalid or unknown configuration keys (the message names the key), a finished run
            whose config or inputs differ or were not recorded (the message names the keys), a results
            folder that cannot be written, or a ``mitsuba`` backend that cannot load (before any work);
            an ``eval.view`` the scene lacks (after loading the scene, before placing).
        SceneError: the scene cannot be loaded, or has no light while the run bakes or evaluates.
        EvaluationUnavailable: ``eval.enabled`` without ``probeplace.evaluate``.
    """
    from .._core.runtime import check_writable_folder

    cfg = to_config(cfg)
    final = run_dir(cfg)
    redo = "all" if force else cfg.redo
    if _results.is_complete(final) and redo != "all":
        stale = finished_run_differences(cfg, run_inputs(cfg.scene), final)
        if stale is None:
            log.info("skip %s (finished)", final)
            return RunResult(final, json.loads((final / RunFiles.metrics).read_text()), skipped=True)
        if redo != "stale":
            raise ConfigError(stale)
        log.info("redo %s: %s", final, stale)
    check_writable_folder(final.parent, "results_dir")  # before the scene is loaded or anything runs
    if cfg.eval.enabled:  # fail before any work, not after the bake
        try:
            from ..evaluate import evaluate  # noqa: F401
        except ImportError:
            raise EvaluationUnavailable(
                "evaluation not available: probeplace.evaluate.evaluate is not built yet; "
                "run with eval.enabled=false"
            ) from None
    _check_backends(cfg)
    run_inputs(cfg.scene)  # a bad sidecar or a missing scene file is refused here, before any work

    partial = _results.begin(final)
    try:
        metrics = _execute(cfg, partial, final)
    except BaseException:  # an error or a signal (SIGTERM → KeyboardInterrupt in experiments/run.py)
        import shutil

        shutil.rmtree(partial, ignore_errors=True)
        raise
    return RunResult(_results.commit(partial, final), metrics)


def _execute(cfg: ExperimentConfig, partial: Path, final: Path) -> dict:
    """Every stage of :func:`run`, writing into ``partial``; returns the metrics."""
    import jax

    from .._core.runtime import progress_bar
    from ..render import resolve_backend
    from ..scene import scene_summary

    (partial / RunFiles.config).write_text(config_to_yaml(cfg))
    _results.write_json(partial / RunFiles.env, _results.environment())
    k_bake, k_eval = jax.random.split(jax.random.key(cfg.seed))
    timings: dict[str, float] = {}
    metrics = _run_record(cfg, final, timings)
    stages = ["scene", "place"] + ["bake"] * cfg.bake.enabled + ["eval"] * cfg.eval.enabled
    stages += ["export"] * bool(cfg.export.formats)
    bar = progress_bar(
        total=len(stages), desc=final.name, unit="stage", disable=not cfg.progress, leave=False
    )

    def stage(name: str) -> None:
        bar.update()
        bar.set_postfix_str(name)

    t0 = time.perf_counter()
    lit = _needs_light(cfg)
    scene, translation = load_experiment_scene(cfg.scene, with_translation=True, require_light=lit)
    timings["scene_s"] = time.perf_counter() - t0
    # the file hashes are cached by size and mtime: run() hashed them already
    inputs = {**run_inputs(cfg.scene), "scene_loaded": scene_summary(scene)}
    _results.write_json(partial / RunFiles.inputs, inputs)
    _check_view(cfg, scene)
    stage("place")
    probes = _place_stage(cfg, scene, translation, partial, final, timings, metrics)
    if cfg.bake.enabled and cfg.eval.enabled:
        _check_tracer_fits(cfg, scene, probes)
    if cfg.bake.enabled:
        stage("bake")
        lf, caster = _bake_stage(cfg, scene, probes, k_bake, partial, timings, metrics)
        if cfg.eval.enabled:
            stage("eval")
            # eval_compile_s: the whole evaluation's compilation; the shading's own is the evaluation's
            # shading_compile_s (first run − median of repeats), its run time shading_s_per_frame
            with _timed(timings, "eval", drjit=resolve_backend(cfg.eval.backend) == "mitsuba"):
                metrics["eval"] = _evaluate(scene, lf, cfg, caster, k_eval, partial)
        if cfg.export.formats:
            stage("export")
            metrics["exported"] = _export_stage(cfg, partial)
    bar.update()
    bar.close()
    timings["place_bake_s"] = timings["place_s"] + timings.get("bake_s", 0.0)
    timings["place_bake_run_s"] = timings["place_run_s"] + timings.get("bake_run_s", 0.0)
    metrics["failures"] = failures(metrics)
    _results.write_json(partial / RunFiles.metrics, metrics)
    return metrics


def _run_record(cfg: ExperimentConfig, final: Path, timings: dict) -> dict:
    """The head of ``metrics.json``: what ran (``timings`` is filled as the stages run)."""
    return {
        "experiment": cfg.name,
        "run": final.name,
        "scene": cfg.scene.name,
        "translate_frac": list(cfg.scene.translate_frac),
        "rotate_deg": float(cfg.scene.rotate_deg),
        "method": cfg.placer.method,
        "refiner": cfg.refiner.name,
        "label": cfg.placer.method + ("" if cfg.refiner.name == "none" else f"+{cfg.refiner.name}"),
        "budget": cfg.placer.budget,
        "seed": cfg.seed,
        "timings": timings,
    }


def _check_view(cfg: ExperimentConfig, scene) -> None:
    """Refuse an evaluation view the scene lacks before placing and baking (``pipeline.check_view``)."""
    from ..pipeline import check_view

    if cfg.eval.enabled:
        check_view(scene, cfg.eval.view, "eval.view", label=cfg.scene.name)


def _needs_light(cfg: ExperimentConfig) -> bool:
    """A run that bakes or evaluates needs a lit scene (placement alone does not)."""
    return bool(cfg.bake.enabled or cfg.eval.enabled)


def check_scenes(cfgs: Iterable[ExperimentConfig]) -> None:
    """Check, before any run starts, what only the loaded scene can tell: each scene of ``cfgs`` loads
    (sidecar and ``scene.overrides`` included; loaded once, unmoved), has light when its run bakes or
    evaluates, and has the run's ``eval.view``, whose camera is in free space (a light that reaches no
    surface the views see is warned about).

    Raises:
        SceneError: a scene that cannot be loaded, or has no light (the message names the sidecar keys).
        ConfigError: ``eval.view: scene ... has no view ...; views: [...]``, or a view camera inside solid
            geometry.
    """
    import json

    from ..evaluate import check_views_and_lights

    loaded: dict[tuple, Any] = {}
    checked: set[tuple] = set()
    for cfg in cfgs:
        overrides = json.dumps(cfg.scene.overrides, sort_keys=True, default=str)
        key = (cfg.scene.name, overrides, _needs_light(cfg))
        if key not in loaded:
            loaded[key] = _load_unmoved(cfg.scene, key[2])
        _check_view(cfg, loaded[key])
        # The evaluate command's checks (a view camera inside a solid: refused; a light that reaches no
        # surface the views see: warned), once per scene and view; host-side Embree rays, no JAX.
        if cfg.eval.enabled and (key, cfg.eval.view) not in checked:
            checked.add((key, cfg.eval.view))
            check_views_and_lights(
                loaded[key], cfg.scene.name, dict(cfg.scene.overrides or {}) or None, view=cfg.eval.view
            )


def _placer_budget(cfg: ExperimentConfig, scene) -> int | str:
    """``placer.budget``, or the count ``placer.memory_budget`` buys at this run's bake settings."""
    from ..pipeline import probe_budget

    if cfg.placer.memory_budget is None:  # no bake settings needed
        return cfg.placer.budget
    return probe_budget(scene, cfg.placer.budget, cfg.placer.memory_budget, bake_config(cfg))


def _place_stage(cfg: ExperimentConfig, scene, translation, partial: Path, final: Path, timings, metrics):
    """Place (timed), record the placement's figures, write ``probes.json`` and the top view."""
    import jax

    from ..pipeline import write_placement
    from ..placement import FitnessConfig, place

    with _timed(timings, "place"):
        placed = place(
            scene,
            method=cfg.placer.method,
            options=_placer_options(cfg, translation),
            config=FitnessConfig(coverage=cfg.placer.coverage),
            **(place_values(cfg) | {"budget": _placer_budget(cfg, scene)}),
        )
        jax.block_until_ready(placed.probes)
    probes = placed.probes
    active = np.asarray(probes.active)
    pos = np.asarray(probes.pos_world)[active]
    metrics.update(
        n_probes=int(active.sum()),
        coverage=placed.coverage,
        target_reached=placed.target_reached,
        min_probe_clearance=placed.min_probe_clearance,
        converged=placed.refine_converged,
        placement_timings=placed.timings,
    )
    metrics["inside_geometry"] = _inside_sdf(scene, pos)
    t0 = time.perf_counter()  # the coverage detail (its own visibility pass, else one more), top view, files
    write_placement(
        scene,
        placed,
        partial / RunFiles.probes,
        png=partial / RunFiles.top_view,
        title=f"{final.name}: {len(pos)} probes",
        metadata=_jsonable(placed.metadata),
    )
    timings["write_placement_s"] = time.perf_counter() - t0
    return probes


def _check_tracer_fits(cfg: ExperimentConfig, scene, probes) -> None:
    """Refuse, before the bake, a placed set whose light-field tracer cannot fit in memory. Every placed
    probe is counted usable (the bake decides which are inside geometry): an upper bound, so a set with
    many probes in walls may be refused that would have fitted. A lod-grid at its automatic budget (2,164
    probes on the Cornell box, 38.5 GiB of tracer maps at 512²) baked for minutes before its tracer was
    refused."""
    from ..probes import check_tracer_memory, map_resolutions

    n = int(np.asarray(probes.active).sum())
    geometry_res = map_resolutions(scene, bake_config(cfg))[1]
    check_tracer_memory(
        n, geometry_res, eval_config(cfg).trace.subdivide, "placed probes (all counted usable)"
    )


def _bake_stage(cfg: ExperimentConfig, scene, probes, key, partial: Path, timings, metrics):
    """Bake (timed) with the reference path tracer, write ``probes_baked.npz``, record the bake's
    settings, how its paths per texel ray were chosen (``bake_samples``; an ``"auto"`` count's pilot is
    timed with the bake) and memory; returns the baked probes and the exact caster (the evaluation's too).
    """
    import jax

    from ..pipeline import bake
    from ..probes import save_probes
    from ..render import default_caster, resolve_backend

    caster = default_caster(scene)
    backend = resolve_backend(cfg.bake.backend)
    with _timed(timings, "bake", drjit=backend == "mitsuba"):
        baked = bake(
            scene,
            probes,
            config=bake_config(cfg),
            spp=cfg.bake.spp,
            eval_max_depth=cfg.tracer.max_depth,
            backend=backend,
            caster=caster,
            key=key,
            pad=cfg.bake.pad_pow2,
        )
        lf = jax.block_until_ready(baked.probes)
    metrics["bake_samples"] = baked.samples.to_dict()
    save_probes(partial / RunFiles.baked, lf)
    metrics["inside_bake"] = int((np.asarray(lf.inside) & np.asarray(lf.active)).sum())
    # the settings stored with the probes (backend included), plus the geometry maps' resolution
    # (interior: the stored maps carry a one-texel border)
    metrics["bake_settings"] = {**lf.bake.to_dict(), "geometry_res": lf.geometry_res}
    # as stored, for the real probes only (padding rows are not part of the method's cost)
    per_probe = _tree_nbytes(lf) / int(lf.pos_world.shape[0])
    metrics["memory"] = {"bytes_per_probe": per_probe, "bytes_total": per_probe * metrics["n_probes"]}
    return lf, caster


def _export_stage(cfg: ExperimentConfig, partial: Path) -> list[str]:
    """Engine exports of the baked probes under ``export/``; their paths relative to the run folder."""
    from ..pipeline import export_baked

    files = export_baked(partial / RunFiles.baked, cfg.export.formats, partial / RunFiles.export_dir)
    return [str(p.relative_to(partial)) for p in files]


# Keys that do not change a run's results: a finished run with other values here is still the same run.
_NOT_RESULTS = ("progress", "results_dir", "redo")
# How a refusal of a finished run ends: the ways out.
_WAYS_OUT = "redo it with redo=stale (run(..., force=True)), use another name=..., or delete the folder"


def _config_differences(cfg: ExperimentConfig, final: Path) -> list[str]:
    """The config keys whose values differ from the finished run's ``config.yaml``."""
    old = _flat(load_config_yaml(final / RunFiles.config))
    new = _flat(config_to_dict(cfg))
    # a key the finished run's config lacks came into the schema later: that run had its default
    default = _flat(config_to_dict(ExperimentConfig()))
    return sorted(
        k
        for k in old.keys() | new.keys()
        if k not in _NOT_RESULTS and old.get(k, default.get(k)) != new.get(k)
    )


def _config_refusal(cfg: ExperimentConfig, final: Path) -> str | None:
    """Why the finished run ``final`` ran with another config (one line naming the keys), or None."""
    diff = _config_differences(cfg, final)
    if not diff:
        return None
    return f"{final} is a finished run with a different config ({', '.join(diff)} differ); {_WAYS_OUT}"


def _check_same_config(cfg: ExperimentConfig, final: Path) -> None:
    """Refuse a finished run that ran with another config, naming the keys."""
    why = _config_refusal(cfg, final)
    if why is not None:
        raise ConfigError(why)


def _short(v) -> str:
    """A recorded value for a message: numbers and short text as they are, a hash cut to 12 characters."""
    text = json.dumps(v)
    if isinstance(v, str) and len(v) > 24:
        return v[:12] + "…"
    return text if len(text) <= 40 else text[:37] + "…"


def _inputs_differences(old: dict, new: dict) -> list[str]:
    """``key (old → new)`` for each compared input key (``_inputs``) whose value differs."""
    a = _flat({k: v for k, v in old.items() if k not in RECORD_ONLY})
    b = _flat({k: v for k, v in new.items() if k not in RECORD_ONLY})
    missing = object()
    out = []
    for k in sorted(a.keys() | b.keys()):
        va, vb = a.get(k, missing), b.get(k, missing)
        if k not in NOT_COMPARED and va != vb:
            show = [("absent" if v is missing else _short(v)) for v in (va, vb)]
            out.append(f"{k} ({show[0]} → {show[1]})")
    return out


def finished_run_differences(cfg: ExperimentConfig, inputs: dict, final: Path) -> str | None:
    """Why the finished run ``final`` is not this run (one line), or None when it is: its config
    (``config.yaml``) or its inputs (``inputs.json``: ``run_inputs``) differ, or its inputs were not
    recorded (a run written before they were)."""
    why = _config_refusal(cfg, final)
    if why is not None:
        return why
    recorded = final / RunFiles.inputs
    if not recorded.is_file():
        return (
            f"{final} is a finished run whose inputs (scene file hash, resolved sidecar, code version) were "
            f"not recorded, so it cannot be checked against this run's; {_WAYS_OUT}"
        )
    try:
        old = json.loads(recorded.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        return f"{final}: inputs.json cannot be read ({type(e).__name__}); {_WAYS_OUT}"
    diff = _inputs_differences(old if isinstance(old, dict) else {}, inputs)
    if diff:
        return f"{final} is a finished run with different inputs ({'; '.join(diff)}); {_WAYS_OUT}"
    return None


def check_finished(cfgs: Iterable[ExperimentConfig]) -> None:
    """Refuse, before any run starts, a run of ``cfgs`` that would meet a finished run it cannot skip
    (:func:`finished_run_differences`) and that ``redo`` does not redo: what ``run`` would refuse later.

    Raises:
        ConfigError: the first such run, its message naming the keys that differ.
    """
    for cfg in cfgs:
        final = run_dir(cfg)
        if cfg.redo == "never" and _results.is_complete(final):
            stale = finished_run_differences(cfg, run_inputs(cfg.scene), final)
            if stale is not None:
                raise ConfigError(stale)


def _inside_sdf(scene, pos: np.ndarray) -> int:
    """Probes with a negative signed distance (inside geometry, the SDF's sign contract; docs/sdf.md)."""
    from ..geometry import build_sdf, lookup_sdf

    if not len(pos):
        return 0
    return int((lookup_sdf(build_sdf(scene), pos) < 0).sum())


def _flat(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def failures(m: dict) -> list[str]:
    """Failure cases of the stability study: coverage < 100% (``placement.reaches_target``, the
    tolerance of ``target_reached``), probes inside geometry (negative SDF or the bake's inside test),
    optimiser not converged, an evaluated error that is not finite or, per indirect component, above a
    black image's (each only when the run measured it). Unresolved rays are a share, not a failure."""
    from ..placement import reaches_target

    out = []
    if m.get("coverage") is not None and not reaches_target(m["coverage"]):
        out.append("coverage<100%")
    if m.get("inside_geometry") or m.get("inside_bake"):
        out.append("inside-geometry")
    if m.get("converged") is False:
        out.append("not-converged")
    e = m.get("eval") or {}
    mses = [e[k] for k in ("mse_glossy_indirect", "mse_diffuse_indirect", "mse_full") if k in e]
    if not all(isinstance(v, int | float) and np.isfinite(v) for v in mses):
        out.append("error-not-finite")
    for c in ("glossy_indirect", "diffuse_indirect"):  # more wrong light than the probes recover
        v, black = e.get(f"mse_{c}"), e.get(f"mse_black_{c}")
        if isinstance(v, int | float) and isinstance(black, int | float) and v > black:
            out.append(f"{c.replace('_', '-')}>black")
    return out


def _jsonable(d):
    if isinstance(d, dict):
        return {str(k): _jsonable(v) for k, v in d.items()}
    if isinstance(d, list | tuple):
        return [_jsonable(v) for v in d]
    if isinstance(d, np.generic):
        return d.item()
    if isinstance(d, np.ndarray):
        return d.tolist()
    if d is None or isinstance(d, str | int | float | bool):
        return d
    return str(d)


__all__ = [
    "ConfigError",
    "EvaluationUnavailable",
    "RunResult",
    "check_finished",
    "check_scenes",
    "run",
    "run_dir",
    "run_name",
]
