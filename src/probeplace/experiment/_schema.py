"""Experiment configuration: one dataclass per Hydra config group, validated with messages naming the key.

The groups (``scene``, ``placer``, ``refiner``, ``bake``, ``tracer``, ``eval``, ``export``) are fields of
:class:`ExperimentConfig`; ``register_configs`` stores the schema in Hydra's ConfigStore as ``base_config``
so that every YAML file under ``configs/`` is merged onto a typed, struct-mode node (unknown keys and wrong
types are rejected by OmegaConf before a run starts). :func:`to_config` does the same for plain dicts, so
tests and notebooks get the same checks without Hydra.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from .._core import ConfigError

#: Placement methods the experiment runner knows. ``grid``, ``lod-grid`` and ``vardis`` are placement
#: methods of ``placement.place`` (issue 6); the runner passes the name through.
PLACERS = ("grid", "lod-grid", "skeleton", "medial", "skeleton+medial", "vardis")
OBJECTIVES = ("coverage", "wang")
SHADINGS = ("lightfield", "irradiance", "sh")


@dataclass
class SceneConfig:
    """Which scene, and a rigid offset of it (stability study: alignment relative to a grid).

    Attributes:
        name: built-in scene name or a file on the scene search path.
        translate_frac: (x, y, z) offset as a fraction of the scene's bounding-box extent per axis.
        rotate_deg: rotation about the vertical (+Y) axis through the bounding-box centre, degrees.
    """

    name: str = "cornell_box"
    translate_frac: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    rotate_deg: float = 0.0


@dataclass
class PlacerConfig:
    """Probe placement (``placement.place``).

    Attributes:
        method: one of :data:`PLACERS`.
        budget: ``"auto"`` (fewest probes reaching ``target`` coverage) or a positive probe count.
        objective: refiner objective, ``coverage`` or ``wang``.
        target: coverage target of the automatic budget, in (0, 1].
        n_opt_samples: surface samples of the refiner's problem.
        options: baseline options of ``grid`` / ``lod-grid`` / ``vardis`` (``placement.place``'s
            ``options``, e.g. ``{jitter: 0.5}`` for the grid); empty for the other methods.
    """

    method: str = "skeleton"
    budget: Any = "auto"
    objective: str = "coverage"
    target: float = 1.0
    n_opt_samples: int = 1500
    options: dict[str, Any] = field(default_factory=dict)


@dataclass
class RefinerConfig:
    """Refinement: ``none`` or a ``placement.REFINERS`` name (a baseline placer refines its survivors)."""

    name: str = "none"


@dataclass
class BakeConfig:
    """Light-field probe bake with the reference path tracer (``probes.bake_probes``).

    Attributes:
        enabled: bake at all (the stability study only needs placements).
        radiance_res: octahedral interior resolution (power of two).
        spp: paths per bake ray; ``n_sub``² jittered rays per texel.
        n_sub: jittered rays per texel per axis.
        probes_per_batch: probes traced at once (memory).
        pad_pow2: pad the baked set with inactive probes to a power-of-two capacity (8 to 64; beyond,
            a multiple of 64), so
            the runs of a sweep share compiled bake / shading code; inactive probes are masked out, the
            results do not change.
        geometry_res: interior resolution of the geometry maps (distance, normal, back-face, distance
            MIPs; a power of two >= 2); ``None`` (default): ``radiance_res``
            (``probes.BakeConfig.geometry_res``: one exact ray per texel, no path tracing).
        backend: who path-traces the bake's radiance: ``"jax"`` (default; the GPU and differentiable
            path) or ``"mitsuba"`` (the same estimator compiled by Mitsuba 3's ``llvm_ad_rgb`` variant,
            several times faster on a CPU; ``probes.path_traced_radiance(backend=...)``). The texel-centre
            geometry rays and the inside test use the exact caster either way. A run refuses
            ``"mitsuba"`` before placing when Mitsuba or its LLVM variant cannot load.

    The bake's path depth is not a setting of its own: it is ``tracer.max_depth − 1``
    (``probes.bake_depth_for``), so the probes always match the reference they are compared with.
    """

    enabled: bool = True
    radiance_res: int = 16
    spp: int = 4
    n_sub: int = 2
    probes_per_batch: int = 4
    pad_pow2: bool = True
    geometry_res: int | None = None
    backend: str = "jax"


@dataclass
class TracerConfig:
    """The reference path tracer of the evaluation (reference image and common random numbers).

    Attributes:
        spp: paths per pixel.
        max_depth: camera path depth in segments (reference render and evaluation); the bake traces
            ``max_depth − 1`` segments from each probe (``probes.bake_depth_for``).
    """

    spp: int = 16
    max_depth: int = 4


@dataclass
class EvalConfig:
    """Evaluation against the path-traced reference (``probeplace.evaluate``).

    Attributes:
        enabled: evaluate at all.
        view: camera name of the scene.
        width: image width in pixels.
        height: image height in pixels.
        glossy_spp: primary samples per pixel of the probe image (one GGX direction each, common
            random numbers with the reference).
        glossy_ref_spp: reference paths per GGX direction (>= 2, for its variance).
        shading: diffuse shading from the probes: ``lightfield``, ``irradiance`` or ``sh``.
        timing_repeats: shading repeats timed (median) after the compile run.
        backend: who path-traces the reference render and the CRN glossy reference: ``"jax"`` (default)
            or ``"mitsuba"`` (``evaluate.EvalConfig.backend``; refused before placing when Mitsuba or its
            LLVM variant cannot load). The tracer's settings (``tracer.spp``, ``tracer.max_depth``) hold
            for either backend.
    """

    enabled: bool = True
    view: str = "front"
    width: int = 64
    height: int = 64
    glossy_spp: int = 8
    glossy_ref_spp: int = 4
    shading: str = "lightfield"
    timing_repeats: int = 3
    backend: str = "jax"


@dataclass
class ExportConfig:
    """Engine exports of the baked probes (``export.export_probes`` format names), e.g. ``[gltf]``."""

    formats: list[str] = field(default_factory=list)


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
    """

    name: str = "default"
    run: str = ""
    results_dir: str = "results"
    seed: int = 0
    progress: bool = True
    scene: SceneConfig = field(default_factory=SceneConfig)
    placer: PlacerConfig = field(default_factory=PlacerConfig)
    refiner: RefinerConfig = field(default_factory=RefinerConfig)
    bake: BakeConfig = field(default_factory=BakeConfig)
    tracer: TracerConfig = field(default_factory=TracerConfig)
    eval: EvalConfig = field(default_factory=EvalConfig)
    export: ExportConfig = field(default_factory=ExportConfig)


def _fail(key: str, what: str, got) -> None:
    raise ConfigError(f"{key}: {what}, got {got!r}")


def _pos_int(key: str, v) -> None:
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        _fail(key, "must be a positive integer", v)


def _pow2(key: str, v) -> None:
    if isinstance(v, bool) or not isinstance(v, int) or v < 2 or v & (v - 1):
        _fail(key, "must be a power of two >= 2", v)


def _backend(key: str, v) -> None:
    from ..render import BACKENDS

    if v not in BACKENDS:
        _fail(key, f"must be one of {BACKENDS}", v)


def _name(key: str, v) -> None:
    if not isinstance(v, str) or not v or "/" in v or v.startswith("."):
        _fail(key, "must be a non-empty name without '/' or a leading '.'", v)


def validate(cfg: ExperimentConfig) -> ExperimentConfig:
    """Check every value of ``cfg``; raise :class:`ConfigError` naming the first bad key."""
    from ..placement import REFINERS

    _name("name", cfg.name)
    if cfg.run:
        _name("run", cfg.run)
    if isinstance(cfg.seed, bool) or not isinstance(cfg.seed, int) or cfg.seed < 0:
        _fail("seed", "must be a non-negative integer", cfg.seed)
    if not isinstance(cfg.scene.name, str) or not cfg.scene.name:
        _fail("scene.name", "must be a scene name or file", cfg.scene.name)
    t = list(cfg.scene.translate_frac)
    if len(t) != 3 or not all(isinstance(x, int | float) and abs(x) <= 0.5 for x in t):
        _fail("scene.translate_frac", "must be three numbers in [-0.5, 0.5]", t)
    if not -180.0 <= float(cfg.scene.rotate_deg) <= 180.0:
        _fail("scene.rotate_deg", "must be in [-180, 180]", cfg.scene.rotate_deg)
    p = cfg.placer
    if p.method not in PLACERS:
        _fail("placer.method", f"must be one of {PLACERS}", p.method)
    if p.budget != "auto" and (isinstance(p.budget, bool) or not isinstance(p.budget, int) or p.budget < 1):
        _fail("placer.budget", "must be 'auto' or a positive integer", p.budget)
    if p.objective not in OBJECTIVES:
        _fail("placer.objective", f"must be one of {OBJECTIVES}", p.objective)
    if not 0.0 < float(p.target) <= 1.0:
        _fail("placer.target", "must be in (0, 1]", p.target)
    _pos_int("placer.n_opt_samples", p.n_opt_samples)
    if p.options:
        from ..placement._place import BASELINE_OPTIONS

        known = BASELINE_OPTIONS.get(p.method, {})
        for k in p.options:
            if k not in known:
                _fail(
                    f"placer.options.{k}",
                    f"not an option of {p.method!r}; known: {sorted(known)}",
                    p.options[k],
                )
    if cfg.refiner.name != "none" and cfg.refiner.name not in REFINERS:
        _fail("refiner.name", f"must be 'none' or one of {REFINERS}", cfg.refiner.name)
    b = cfg.bake
    _pow2("bake.radiance_res", b.radiance_res)
    if b.geometry_res is not None:
        _pow2("bake.geometry_res", b.geometry_res)
    for k in ("spp", "n_sub", "probes_per_batch"):
        _pos_int(f"bake.{k}", getattr(b, k))
    _backend("bake.backend", b.backend)
    _pos_int("tracer.spp", cfg.tracer.spp)
    if (
        isinstance(cfg.tracer.max_depth, bool)
        or not isinstance(cfg.tracer.max_depth, int)
        or cfg.tracer.max_depth < 3
    ):
        _fail(
            "tracer.max_depth",
            "must be an integer >= 3 (indirect light needs two bounces)",
            cfg.tracer.max_depth,
        )
    for k in ("width", "height", "glossy_spp", "timing_repeats"):
        _pos_int(f"eval.{k}", getattr(cfg.eval, k))
    if (
        isinstance(cfg.eval.glossy_ref_spp, bool)
        or not isinstance(cfg.eval.glossy_ref_spp, int)
        or cfg.eval.glossy_ref_spp < 2
    ):
        _fail("eval.glossy_ref_spp", "must be an integer >= 2", cfg.eval.glossy_ref_spp)
    if cfg.eval.shading not in SHADINGS:
        _fail("eval.shading", f"must be one of {SHADINGS}", cfg.eval.shading)
    _backend("eval.backend", cfg.eval.backend)
    if cfg.eval.enabled and not cfg.bake.enabled:
        _fail("eval.enabled", "needs baked probes (bake.enabled=true)", cfg.eval.enabled)
    from ..export._registry import FORMATS

    for i, f in enumerate(cfg.export.formats):
        if f not in FORMATS:
            _fail(f"export.formats[{i}]", f"must be one of {sorted(FORMATS)}", f)
    if cfg.export.formats and not cfg.bake.enabled:
        _fail("export.formats", "needs baked probes (bake.enabled=true)", list(cfg.export.formats))
    return cfg


def to_config(cfg: Any) -> ExperimentConfig:
    """An :class:`ExperimentConfig` from a dataclass, dict or OmegaConf node, checked against the schema
    (unknown keys, wrong types) and validated. Errors are :class:`ConfigError` naming the key."""
    from omegaconf import OmegaConf
    from omegaconf.errors import OmegaConfBaseException

    if isinstance(cfg, ExperimentConfig):
        return validate(cfg)
    try:
        base = OmegaConf.structured(ExperimentConfig)  # dataclass nodes refuse unknown keys
        node = OmegaConf.create(cfg) if isinstance(cfg, dict) else cfg
        stale = OmegaConf.select(node, "bake.max_depth") if OmegaConf.is_config(node) else None
        if stale is not None:
            raise ConfigError(
                f"bake.max_depth={stale}: the bake's path depth is no longer "
                "a setting, it is tracer.max_depth − 1 (probes.bake_depth_for); remove bake.max_depth and "
                "set tracer.max_depth (a run folder written with it was baked at its own depth: re-run it)"
            )
        if OmegaConf.is_config(node) and "hydra" in node:
            node = OmegaConf.masked_copy(node, [k for k in node if k != "hydra"])
        merged = OmegaConf.merge(base, node)
        obj = OmegaConf.to_object(merged)
    except OmegaConfBaseException as e:
        key = getattr(e, "full_key", None) or "config"
        msg = str(e).splitlines()[0]
        raise ConfigError(f"{key}: {msg}") from None
    assert isinstance(obj, ExperimentConfig)
    return validate(obj)


def config_to_dict(cfg: ExperimentConfig) -> dict:
    """Plain nested dict of a config (for YAML/JSON)."""
    return dataclasses.asdict(cfg)


def register_configs() -> None:
    """Store the schema in Hydra's ConfigStore as ``base_config`` (configs/config.yaml lists it first)."""
    from hydra.core.config_store import ConfigStore

    ConfigStore.instance().store(name="base_config", node=ExperimentConfig)
