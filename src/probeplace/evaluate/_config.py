"""Evaluation settings (docs/evaluate.md)."""

from __future__ import annotations

import dataclasses
import math

from .._core import ConfigError, check_count, check_target, is_auto
from ..probes import DEFAULT_GLOSSY_FILTER, GLOSSY_FILTERS, SHADINGS, TraceConfig
from ._decompose import LEAK_SIGMAS


@dataclasses.dataclass(frozen=True, kw_only=True)
class EvalConfig:
    """Evaluation settings.

    Attributes:
        width, height: image size.
        spp: reference paths per pixel (the render of every component), or ``"auto"``: the fewest whose
            diffuse-indirect noise floor is at most ``noise_target`` × that component's black-image MSE,
            from a pilot render (``evaluate._samples``).
        glossy_spp: primary samples per pixel for the probe image, each with one GGX direction (CRN).
        glossy_ref_spp: paths per GGX direction for the CRN reference (≥ 2, for its variance), or
            ``"auto"``: the fewest whose glossy-indirect noise floor meets ``noise_target`` likewise.
        noise_target: the reference noise floor a chosen count aims at, as a fraction of the scored
            component's black-image MSE (0.05: the floor is 5 % of it), in (0, 1).
        pilot_spp: paths per pixel (per GGX direction) of the pilot passes of an ``"auto"`` count (≥ 2:
            the floor is a sample variance).
        max_spp: the most paths per pixel (per GGX direction) an ``"auto"`` count may reach; a run that
            needs more proceeds at the cap and says ``target_met: false``.
        max_depth: longest path in segments (≥ 3: indirect light needs two bounces).
        shading: diffuse method, ``"lightfield"`` | ``"irradiance"`` | ``"sh"``.
        trace: light-field tracer settings (glossy rays).
        glossy_filter: how glossy rays read the radiance map at their hit: ``"texel"`` (one texel,
            unfiltered), ``"bilinear"``, ``"depth_aware"`` (default: bilinear over the texels whose surfel
            lies at the hit; on Sponza 16×8×8 at 64² it lowered the glossy MSE 1.95 → 1.81× and the
            perfect trace 0.99 → 0.82× the black image, at 32² 4.4 → 2.2×) or ``"mip"``
            (footprint-driven MIP level, probes/_glossy.py). Against the CRN reference, which scores
            each direction by itself, the lobe-wide MIP read blurs every sample and measured 4× the
            bilinear MSE (docs/evaluate.md).
        glossy_lod_bias: added to the MIP level of ``"mip"`` reads.
        perfect_trace_margin: visibility margin of the perfect-trace probe choice (fraction of the
            probe–hit distance; ``probes.perfect_trace_radiance``).
        agreement_rtol: a resolved light-field hit agrees with the exact hit when |t_lf − t_exact| ≤
            rtol · t_exact + 1e-4 × the scene diagonal.
        bootstrap_resamples: resamples of the pixels for the 95% confidence intervals (fixed seed 0).
        relmse_eps: ε of the relative MSE, as a fraction of the squared mean reference luminance.
        seed: random seed (used when no key is given).
        normal_bias: Chebyshev receiver offset (× probe spacing), see ``probes.diffuse_irradiance``.
        leak_sigmas: a pixel leaks light when the probes' diffuse indirect exceeds the reference's by more
            than this many of the reference's own standard errors (``_decompose.light_leak``).
        timing_repeats: shading repeats timed (median) after the compile run.
        progress: progress bars for the reference render.
        backend: who path-traces the reference render and the CRN glossy reference: ``"jax"`` (default)
            or ``"mitsuba"`` (the same model and random numbers in Dr.Jit, several times faster on a CPU;
            ``render.RenderConfig.backend``), or ``"auto"`` (replaced by ``render.resolve_backend``'s
            pick). The exact caster of the primary hits and the perfect trace
            is the ``caster`` argument either way.
    """

    width: int = 64
    height: int = 64
    spp: int | str = 64
    glossy_spp: int = 8
    glossy_ref_spp: int | str = 4
    noise_target: float = 0.05
    pilot_spp: int = 8
    max_spp: int = 1024
    max_depth: int = 8
    shading: str = "lightfield"
    trace: TraceConfig = dataclasses.field(default_factory=TraceConfig)
    glossy_filter: str = DEFAULT_GLOSSY_FILTER
    glossy_lod_bias: float = 0.0
    perfect_trace_margin: float = 0.05
    agreement_rtol: float = 0.02
    bootstrap_resamples: int = 1000
    relmse_eps: float = 0.01
    seed: int = 0
    normal_bias: float = 0.2
    leak_sigmas: float = LEAK_SIGMAS
    timing_repeats: int = 3
    progress: bool = False
    backend: str = "jax"

    def __post_init__(self):
        for name in ("width", "height", "glossy_spp", "timing_repeats", "bootstrap_resamples"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ConfigError(f"EvalConfig.{name} must be a positive int, got {v!r}")
        check_count(self.spp, "EvalConfig.spp")
        check_count(self.glossy_ref_spp, "EvalConfig.glossy_ref_spp", minimum=2)
        check_target(
            "EvalConfig",
            noise_target=self.noise_target,
            pilot_spp=self.pilot_spp,
            max_spp=self.max_spp,
            min_pilot=2,
        )
        if not isinstance(self.max_depth, int) or self.max_depth < 3:
            raise ConfigError(f"EvalConfig.max_depth must be an int ≥ 3, got {self.max_depth!r}")
        from ..render import resolve_backend

        object.__setattr__(self, "backend", resolve_backend(self.backend, "EvalConfig.backend"))
        if self.shading not in SHADINGS:
            raise ConfigError(f"EvalConfig.shading must be one of {SHADINGS}, got {self.shading!r}")
        if self.glossy_filter not in GLOSSY_FILTERS:
            raise ConfigError(
                f"EvalConfig.glossy_filter must be one of {GLOSSY_FILTERS}, got {self.glossy_filter!r}"
            )
        if not isinstance(self.glossy_lod_bias, int | float) or not math.isfinite(self.glossy_lod_bias):
            raise ConfigError(
                f"EvalConfig.glossy_lod_bias must be a finite number, got {self.glossy_lod_bias!r}"
            )
        if not isinstance(self.trace, TraceConfig):
            raise ConfigError(f"EvalConfig.trace must be a TraceConfig, got {type(self.trace).__name__}")
        if not self.normal_bias >= 0:
            raise ConfigError(f"EvalConfig.normal_bias must be ≥ 0, got {self.normal_bias!r}")
        if not self.leak_sigmas > 0:
            raise ConfigError(f"EvalConfig.leak_sigmas must be > 0, got {self.leak_sigmas!r}")
        if not 0 <= self.perfect_trace_margin < 1 or not self.agreement_rtol >= 0 or not self.relmse_eps > 0:
            raise ConfigError(
                "EvalConfig.perfect_trace_margin must be in [0, 1), agreement_rtol ≥ 0 and relmse_eps > 0"
            )


def check_eval_memory(config, what: str) -> None:
    """Refuse an evaluation whose reference render would not fit in memory, before anything is loaded
    (the renderer's own estimate, ``_core.runtime._checks.check_image_memory``); an ``"auto"`` count is
    checked at its cap ``max_spp``, the most it may render."""
    from .._core.runtime import check_image_memory
    from ..render import COMPONENTS, RenderConfig

    check_image_memory(
        config.width,
        config.height,
        config.max_spp if is_auto(config.spp) else config.spp,
        components=len(COMPONENTS),
        paths_per_batch=RenderConfig.paths_per_batch,
        what=what,
    )
