"""Experiment configuration: one dataclass per config group, validated with messages naming the key.

The groups (``scene``, ``placer``, ``refiner``, ``bake``, ``tracer``, ``eval``, ``export``) are fields of
:class:`ExperimentConfig`. The ``bake`` and ``eval`` groups are *built from* the library's own settings
(``probes.BakeConfig``, ``evaluate.EvalConfig``): every scalar field of those is a key of the group, with
the library's type, default and checks, plus the few keys only the runner has (``enabled``, ``view``,
the bake's ``spp`` / ``pad_pow2`` / ``backend``). :func:`validate` builds the library configs from a run's
config, so their checks run once, in the library, before any work; their messages are re-keyed to the
config key (``bake.radiance_res: ...``).

Neither Hydra nor OmegaConf is imported here: :func:`to_config` turns any mapping (an OmegaConf node is
one) into the typed config itself (``_typed``); ``experiments/run.py`` registers :class:`ExperimentConfig`
in Hydra's ConfigStore.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from .._core import ConfigError, check_count, is_auto
from .._core.runtime import rekeyed
from ..evaluate import EvalConfig as _LibEvalConfig
from ..placement import LIBRARY_ONLY as _LIBRARY_ONLY
from ..placement import PlaceRequest as _PlaceRequest
from ..probes import BakeConfig as _LibBakeConfig
from ..probes import TraceConfig as _LibTraceConfig
from ..render import RenderConfig as _LibRenderConfig
from ._typed import from_mapping


@dataclass
class SceneStage:
    """Which scene, its light and cameras, and a rigid offset of it (stability study: alignment relative
    to a grid).

    Attributes:
        name: built-in scene name, a file on the scene search path, or a file's path (its sidecar
            ``<stem>.probeplace.yaml`` beside it is read, docs/scenes.md "Sidecar config").
        translate_frac: (x, y, z) offset as a fraction of the scene's bounding-box extent per axis.
        rotate_deg: rotation about the vertical (+Y) axis through the bounding-box centre, degrees.
        overrides: sidecar keys over the file's own sidecar (``load_scene(..., overrides=...)``: ``sun``,
            ``sky``, ``cameras``, ``emitters``, ``materials``, ``units``, ...), e.g.
            ``+scene.overrides.sky=daylight``; checked like a sidecar before any run starts.
    """

    name: str = "cornell_box"
    translate_frac: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    rotate_deg: float = 0.0
    overrides: dict[str, Any] = field(default_factory=dict)


@dataclass
class RefinerConfig:
    """Refinement: ``none`` or a ``placement.REFINERS`` name (a baseline placer refines its survivors)."""

    name: str = "none"


_SCALARS = (bool, int, float, str)


def _is_scalar(tp: Any) -> bool:
    """A type a config key may have: a scalar, a union of scalars (``int | str``: a count or ``"auto"``)
    or either ``| None`` (nested settings stay library-only)."""
    if tp in _SCALARS:
        return True
    args = [a for a in typing.get_args(tp) if a is not type(None)]
    union = typing.get_origin(tp) in (typing.Union, types.UnionType)
    return union and bool(args) and all(a in _SCALARS for a in args)


def _is_key(f: dataclasses.Field, tp: Any) -> bool:
    """A library field that is a config key: a scalar (:func:`_is_scalar`), or a field whose ``help``
    metadata offers it to the front doors (``placement.PlaceRequest``: ``region``, a mapping)."""
    help_text = f.metadata.get("help")
    return _is_scalar(tp) if help_text is None else help_text != _LIBRARY_ONLY


def _stage_schema(name: str, doc: str, lib: type, *, head: list, tail: list, runner_set: set, defaults: dict):
    """The config group of a library settings dataclass ``lib``: ``head``, then every scalar field of
    ``lib`` not set by the runner itself (``runner_set``), with ``lib``'s type and default (or
    ``defaults``'), then ``tail``. A field added to ``lib`` becomes a key of the group without an edit here.
    """
    hints = typing.get_type_hints(lib)
    own = [
        (f.name, hints[f.name], field(default=defaults.get(f.name, f.default)))
        for f in dataclasses.fields(lib)
        if f.name not in runner_set and _is_key(f, hints[f.name])
    ]
    cls = dataclasses.make_dataclass(name, [*head, *own, *tail])
    # make_dataclass would name the module ``types`` (Python 3.11): pickling (joblib / Ray launchers) finds
    # the class by its module
    cls.__module__, cls.__doc__ = __name__, doc
    return cls


PlacerConfig = _stage_schema(
    "PlacerConfig",
    """Probe placement (``placement.place``).

    Every field of ``placement.PlaceRequest`` (the stage's one schema) is a key, with its type, default
    and checks, but those the runner sets: ``refiner`` (the ``refiner`` group), ``seed`` (the run's) and the
    library-only ``config`` and ``caster``. A field added to ``PlaceRequest`` becomes a key here, a flag of
    ``probeplace place`` and a keyword of ``place`` without another edit. The runner's own:

    Attributes:
        method: a registered placement method (``placement.METHODS``).
        memory_budget: instead of ``budget``, the bytes the baked probes may take (``"64MiB"``): the count
            is the most probes whose maps fit at this experiment's bake settings (``probes.probe_bytes``).
        coverage: which surface counts toward coverage: ``reachable`` (every surface a probe in the views'
            reachable space sees head-on) or ``views`` (what the view cameras' positions see;
            ``placement.FitnessConfig.coverage``).
        options: the method's options (``placement.place``'s ``options``, e.g. ``{jitter: 0.5}`` for the
            grid); empty for methods without options.
    """,
    _PlaceRequest,
    head=[("method", str, field(default="skeleton"))],
    tail=[
        ("memory_budget", Any, field(default=None)),
        ("coverage", str, field(default="reachable")),
        ("options", dict[str, Any], field(default_factory=dict)),
    ],
    runner_set={"refiner", "seed"},
    defaults={},
)


BakeStage = _stage_schema(
    "BakeStage",
    """Light-field probe bake with the reference path tracer (``probes.bake_probes``).

    Every scalar field of ``probes.BakeConfig`` but ``progress`` (the run's ``progress``) is a key, with its
    meaning and checks; ``radiance_res`` defaults to 16 and ``probes_per_batch`` to 4 here. The runner's own:

    Attributes:
        enabled: bake at all (the stability study only needs placements).
        spp: paths per bake ray (``probes.path_traced_radiance``; checked as ``render.RenderConfig.spp``),
            or ``"auto"``: chosen by a pilot for the radiance maps' relative noise ``noise_target``, from
            ``pilot_spp`` up to ``max_spp`` (``probes.choose_bake_spp``; ``metrics.json``'s
            ``bake_samples``).
        pad_pow2: pad the baked set with inactive probes to a power-of-two capacity (8 to 64; beyond, a
            multiple of 64: ``probes.pad_probes``), so the runs of a sweep share compiled bake / shading
            code; inactive probes are masked out, the results do not change. ``probeplace evaluate``
            always pads.
        backend: who path-traces the bake's radiance: ``"jax"`` (default) or ``"mitsuba"`` (Mitsuba 3's
            ``llvm_ad_rgb`` variant; ``probes.path_traced_radiance(backend=...)``), or ``"auto"``
            (``render.resolve_backend``: Mitsuba on a CPU where it loads, else JAX). A run refuses
            ``"mitsuba"`` before placing when Mitsuba or its LLVM variant cannot load.

    The bake's path depth is not a setting of its own: it is ``tracer.max_depth − 1``
    (``probes.bake_depth_for``), so the probes always match the reference they are compared with.
    """,
    _LibBakeConfig,
    head=[("enabled", bool, field(default=True))],
    tail=[
        ("spp", int | str, field(default=4)),
        ("pad_pow2", bool, field(default=True)),
        ("backend", str, field(default="jax")),
    ],
    runner_set={"progress"},
    defaults={"radiance_res": 16, "probes_per_batch": 4},
)


_EVAL_DEFAULTS = {f.name: f.default for f in dataclasses.fields(_LibEvalConfig)}


@dataclass
class TracerConfig:
    """The reference path tracer of the evaluation (reference image and common random numbers).

    Attributes:
        spp: paths per pixel (``evaluate.EvalConfig.spp``), or ``"auto"``: chosen by a pilot render so that
            the diffuse indirect's noise floor is at most ``noise_target`` × its black-image MSE
            (``evaluate._samples``; ``eval.glossy_ref_spp: auto`` does the same for the glossy CRN
            reference).
        max_depth: camera path depth in segments (``evaluate.EvalConfig.max_depth``); the bake traces
            ``max_depth − 1`` segments from each probe (``probes.bake_depth_for``).
        noise_target: the reference noise floor an ``"auto"`` count aims at, as a fraction of the black
            image's MSE (``evaluate.EvalConfig.noise_target``).
        pilot_spp: paths of the pilot passes of an ``"auto"`` count (``evaluate.EvalConfig.pilot_spp``).
        max_spp: the cap of an ``"auto"`` count (``evaluate.EvalConfig.max_spp``).
    """

    spp: int | str = 16
    max_depth: int = 4
    noise_target: float = _EVAL_DEFAULTS["noise_target"]
    pilot_spp: int = _EVAL_DEFAULTS["pilot_spp"]
    max_spp: int = _EVAL_DEFAULTS["max_spp"]


#: The ``tracer`` keys that are ``evaluate.EvalConfig`` fields of the same name, beside ``spp`` and
#: ``max_depth``: how an ``"auto"`` count is chosen.
_TRACER_KEYS = ("noise_target", "pilot_spp", "max_spp")

EvalStage = _stage_schema(
    "EvalStage",
    """Evaluation against the path-traced reference (``probeplace.evaluate``).

    Every scalar field of ``evaluate.EvalConfig`` is a key, with its meaning and checks, but those the
    runner sets: ``spp``, ``max_depth`` and the noise target's ``noise_target``, ``pilot_spp``, ``max_spp``
    (the ``tracer`` group), ``progress`` (the run's) and ``seed`` (the run's key). The runner's own:

    Attributes:
        enabled: evaluate at all.
        view: camera name of the scene.
        trace_engine: how the light-field tracer runs the glossy rays (``probes.TraceConfig.engine``):
            ``"wavefront"`` (default: the per-ray engine's hits, ~20× faster shading on the Cornell demo at
            64² geometry maps, 3× its compile time) or ``"per_ray"`` (the engine it is held to).
    """,
    _LibEvalConfig,
    head=[("enabled", bool, field(default=True)), ("view", str, field(default="front"))],
    tail=[("trace_engine", str, field(default="wavefront"))],
    runner_set={"spp", "max_depth", "progress", "seed", *_TRACER_KEYS},
    defaults={},
)


LightFieldStage = _stage_schema(
    "LightFieldStage",
    """The light-field tracer of the evaluation's glossy rays (``probes.TraceConfig``, docs/tracer.md).

    Every scalar field of ``probes.TraceConfig`` is a key, with its meaning, default and checks, but
    ``engine`` (``eval.trace_engine``, whose default here is ``"wavefront"``). Not to be confused with the
    ``tracer`` group, the reference path tracer.
    """,
    _LibTraceConfig,
    head=[],
    tail=[],
    runner_set={"engine"},
    defaults={},
)


@dataclass
class ExportConfig:
    """Engine exports of the baked probes (``export.export_probes`` format names), e.g. ``[gltf]``."""

    formats: list[str] = field(default_factory=list)


#: The values of ``ExperimentConfig.redo``.
REDO = ("never", "stale", "all")


@dataclass
class ExperimentConfig:
    """One run: scene × placer × refiner × seed, and how it is baked, evaluated and exported.

    Attributes:
        name: experiment name: results go to ``results_dir/name/<run>/`` (a preset sets it; a config
            field called ``experiment`` would clash with the ``+experiment=<preset>`` group).
        run: run folder name; empty derives it from scene, method, refiner, budget and seed.
        results_dir: root of all results.
        seed: PRNG seed of the whole run (placement, bake, evaluation get split keys).
        progress: show progress bars.
        redo: what to do with a finished run folder: ``never`` (skip it when it ran with this config and
            these inputs, ``inputs.json``; refuse it, naming the keys, when they differ or were not
            recorded), ``stale`` (redo it in those cases, skip it otherwise) or ``all`` (redo it always).
            Not part of a run's identity.
    """

    name: str = "default"
    run: str = ""
    results_dir: str = "results"
    seed: int = 0
    progress: bool = True
    redo: str = "never"
    scene: SceneStage = field(default_factory=SceneStage)
    placer: PlacerConfig = field(default_factory=PlacerConfig)
    refiner: RefinerConfig = field(default_factory=RefinerConfig)
    bake: BakeStage = field(default_factory=BakeStage)
    tracer: TracerConfig = field(default_factory=TracerConfig)
    eval: EvalStage = field(default_factory=EvalStage)
    lightfield: LightFieldStage = field(default_factory=LightFieldStage)
    export: ExportConfig = field(default_factory=ExportConfig)


def _library_values(stage: Any, lib: type) -> dict:
    names = {f.name for f in dataclasses.fields(lib)}
    return {k: v for k, v in dataclasses.asdict(stage).items() if k in names}


def place_values(cfg: ExperimentConfig) -> dict:
    """The ``placement.place`` settings (``PlaceRequest`` fields) a run places with: the ``placer``
    group's, the ``refiner`` group's name and the run's seed (its ``budget`` as given: the runner turns a
    ``memory_budget`` into a count once the scene is loaded)."""
    refiner = None if cfg.refiner.name == "none" else cfg.refiner.name
    return {**_library_values(cfg.placer, _PlaceRequest), "refiner": refiner, "seed": cfg.seed}


def trace_values(cfg: ExperimentConfig) -> dict:
    """The keyword arguments of ``probes.TraceConfig`` a run traces its glossy rays with: the
    ``lightfield`` group's keys and ``eval.trace_engine``."""
    return {**_library_values(cfg.lightfield, _LibTraceConfig), "engine": cfg.eval.trace_engine}


def bake_values(cfg: ExperimentConfig) -> dict:
    """The keyword arguments of ``probes.BakeConfig`` a run bakes with: the ``bake`` group's library keys,
    the run's ``progress``. ``probeplace evaluate`` takes its bake defaults from these of
    ``ExperimentConfig()`` (the evaluate command, cli/_evaluate.py): one place for the defaults of both."""
    return {**_library_values(cfg.bake, _LibBakeConfig), "progress": cfg.progress}


def eval_values(cfg: ExperimentConfig) -> dict:
    """The keyword arguments of ``evaluate.EvalConfig`` a run evaluates with, but ``trace`` (built from
    ``eval.trace_engine``) and ``seed`` (the run's key): the ``eval`` group's library keys, the tracer's
    samples and depth, the run's ``progress``. ``probeplace evaluate`` takes its defaults from these of
    ``ExperimentConfig()`` (the evaluate command, cli/_evaluate.py)."""
    return {
        **_library_values(cfg.eval, _LibEvalConfig),
        "spp": cfg.tracer.spp,
        "max_depth": cfg.tracer.max_depth,
        **{k: getattr(cfg.tracer, k) for k in _TRACER_KEYS},
        "progress": cfg.progress,
    }


def bake_config(cfg: ExperimentConfig) -> _LibBakeConfig:
    """The library's bake settings of a run (``probes.BakeConfig``)."""
    values = bake_values(cfg)
    return rekeyed(_LibBakeConfig, values, {k: f"bake.{k}" for k in values})


def eval_config(cfg: ExperimentConfig) -> _LibEvalConfig:
    """The library's evaluation settings of a run (``evaluate.EvalConfig``): the ``eval`` group, the
    tracer's samples and depth, the run's ``progress``."""
    values = eval_values(cfg)
    keys = {k: f"eval.{k}" for k in values}
    keys |= {k: f"tracer.{k}" for k in ("spp", "max_depth", *_TRACER_KEYS)}
    trace = trace_values(cfg)
    trace_keys = {k: f"lightfield.{k}" for k in trace} | {"engine": "eval.trace_engine"}
    values["trace"] = rekeyed(_LibTraceConfig, trace, trace_keys)
    return rekeyed(_LibEvalConfig, values, keys)


def _check_bake_tracer(cfg: ExperimentConfig) -> None:
    """The bake's path tracer settings, checked where the renderer checks them (``RenderConfig``; the
    image size is a placeholder, a bake has none); ``spp`` may also be ``"auto"`` (``probes.choose_bake_spp``
    checks it, and ``BakeConfig`` its pilot and cap)."""
    try:
        check_count(cfg.bake.spp, "bake.spp")
    except ConfigError as e:
        raise ConfigError(str(e).replace("bake.spp must", "bake.spp: must", 1)) from None
    spp = 1 if is_auto(cfg.bake.spp) else cfg.bake.spp
    values = {"width": 1, "height": 1, "spp": spp, "backend": cfg.bake.backend}
    rekeyed(_LibRenderConfig, values, {"spp": "bake.spp", "backend": "bake.backend"})


def _fail(key: str, what: str, got) -> None:
    raise ConfigError(f"{key}: {what}, got {got!r}")


def _name(key: str, v) -> None:
    if not isinstance(v, str) or not v or "/" in v or v.startswith("."):
        _fail(key, "must be a non-empty name without '/' or a leading '.'", v)


def _check_run(cfg: ExperimentConfig) -> None:
    _name("name", cfg.name)
    if cfg.run:
        _name("run", cfg.run)
    if isinstance(cfg.seed, bool) or not isinstance(cfg.seed, int) or cfg.seed < 0:
        _fail("seed", "must be a non-negative integer", cfg.seed)
    if cfg.redo not in REDO:
        _fail("redo", f"must be one of {', '.join(REDO)}", cfg.redo)
    if not isinstance(cfg.scene.name, str) or not cfg.scene.name:
        _fail("scene.name", "must be a scene name or file", cfg.scene.name)
    t = list(cfg.scene.translate_frac)
    if len(t) != 3 or not all(isinstance(x, int | float) and abs(x) <= 0.5 for x in t):
        _fail("scene.translate_frac", "must be three numbers in [-0.5, 0.5]", t)
    if not -180.0 <= float(cfg.scene.rotate_deg) <= 180.0:
        _fail("scene.rotate_deg", "must be in [-180, 180]", cfg.scene.rotate_deg)
    from ..scene import parse_scene_config

    parse_scene_config(cfg.scene.overrides or None, "scene.overrides")  # the sidecar's own checks


def _check_placer(cfg: ExperimentConfig) -> None:
    """The placement settings, checked where ``place`` checks them (``placement.PlaceRequest``)."""
    from ..placement import COVERAGE_RULES, PlaceRequest, Region, method_names, method_options, parse_bytes

    p = cfg.placer
    if p.method not in method_names():
        _fail("placer.method", f"must be one of {method_names()}", p.method)
    if p.coverage not in COVERAGE_RULES:
        _fail("placer.coverage", f"must be one of {COVERAGE_RULES}", p.coverage)
    values = place_values(cfg)
    keys = {**{k: f"placer.{k}" for k in values}, "refiner": "refiner.name", "seed": "seed"}
    try:
        Region.from_config(p.region)  # its messages name the key under region: region.boxes[1][0] ...
    except ConfigError as e:
        raise ConfigError(f"placer.{e}") from None
    rekeyed(PlaceRequest, values, keys)
    if p.memory_budget is not None:
        if p.budget != "auto":
            _fail("placer.budget", "must be 'auto' when placer.memory_budget is given", p.budget)
        try:
            parse_bytes(p.memory_budget)
        except ConfigError as e:
            raise ConfigError(f"placer.memory_budget: {e}") from None
    known = method_options(p.method)
    for k in p.options or {}:
        if k not in known:
            _fail(
                f"placer.options.{k}", f"not an option of {p.method!r}; known: {sorted(known)}", p.options[k]
            )


def _check_outputs(cfg: ExperimentConfig) -> None:
    from ..export import FORMATS

    if cfg.eval.enabled and not cfg.bake.enabled:
        _fail("eval.enabled", "needs baked probes (bake.enabled=true)", cfg.eval.enabled)
    for i, f in enumerate(cfg.export.formats):
        if f not in FORMATS:
            _fail(f"export.formats[{i}]", f"must be one of {sorted(FORMATS)}", f)
    if cfg.export.formats and not cfg.bake.enabled:
        _fail("export.formats", "needs baked probes (bake.enabled=true)", list(cfg.export.formats))


def _check_sizes(cfg: ExperimentConfig, bake, ev) -> None:
    """Refuse, before any work, a bake batch or an evaluation image that would not fit in memory (the
    estimates ``bake_probes`` and the renderer make, for one probe and the run's image)."""
    from .._core import check_memory
    from ..evaluate import check_eval_memory

    if cfg.bake.enabled and bake.radiance_res:
        res, geo = bake.radiance_res, bake.geometry_res or bake.radiance_res
        need = res * res * bake.n_sub**2 * 200 + (res + 2) ** 2 * 48 + (geo + 2) ** 2 * 58
        what = f"bake.radiance_res={res}, bake.geometry_res={geo}, bake.n_sub={bake.n_sub}: one probe's bake"
        check_memory(need, what, "lower bake.radiance_res, bake.geometry_res or bake.n_sub")
    if cfg.eval.enabled:
        check_eval_memory(ev, "eval.width × eval.height: the reference render")


def validate(cfg: ExperimentConfig) -> ExperimentConfig:
    """Check every value of ``cfg``; raise :class:`ConfigError` naming the first bad key (or
    ``ResourceError`` for a bake or image that would not fit in memory). The bake and evaluation settings
    are checked by building the library's configs (also for a disabled stage: a bad value is refused
    whether or not it is used)."""
    _check_run(cfg)
    _check_placer(cfg)
    bake = bake_config(cfg)
    _check_bake_tracer(cfg)
    ev = eval_config(cfg)
    _check_outputs(cfg)
    _check_sizes(cfg, bake, ev)
    return cfg


def to_config(cfg: Any) -> ExperimentConfig:
    """An :class:`ExperimentConfig` from a dataclass or any mapping (a dict, an OmegaConf node), checked
    against the schema (unknown keys, wrong types) and validated. Errors are :class:`ConfigError` naming the
    key. A ``hydra`` key (Hydra's own node, when composed with it) is ignored."""
    if isinstance(cfg, ExperimentConfig):
        return validate(cfg)
    if isinstance(cfg, Mapping):
        _refuse_stale_keys(cfg)
        cfg = {k: cfg[k] for k in cfg if k != "hydra"}  # never read Hydra's node
    return validate(from_mapping(ExperimentConfig, cfg))


def _refuse_stale_keys(cfg: Mapping) -> None:
    bake = cfg.get("bake")
    stale = bake.get("max_depth") if isinstance(bake, Mapping) else None
    if stale is not None:
        raise ConfigError(
            f"bake.max_depth={stale}: the bake's path depth is no longer "
            "a setting, it is tracer.max_depth − 1 (probes.bake_depth_for); remove bake.max_depth and "
            "set tracer.max_depth (a run folder written with it was baked at its own depth: re-run it)"
        )


def config_to_dict(cfg: ExperimentConfig) -> dict:
    """Plain nested dict of a config (for YAML/JSON)."""
    return dataclasses.asdict(cfg)


def config_to_yaml(cfg: ExperimentConfig) -> str:
    """The config as YAML, keys in schema order (a run folder's ``config.yaml``)."""
    import yaml

    return yaml.safe_dump(config_to_dict(cfg), sort_keys=False, allow_unicode=True, default_flow_style=False)


def load_config_yaml(path) -> dict:
    """A ``config.yaml`` as a plain dict (pass it to :func:`to_config` for the typed config)."""
    from pathlib import Path

    import yaml

    return yaml.safe_load(Path(path).read_text()) or {}
