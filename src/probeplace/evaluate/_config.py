"""Evaluation settings (docs/evaluate.md)."""

from __future__ import annotations

import dataclasses

from .._core import ConfigError, check_count, check_target, is_auto
from .._core.runtime import check_settings, setting
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
            unfiltered), ``"bilinear"``, ``"depth_aware"`` (bilinear over the texels whose surfel lies at
            the hit; on Sponza 16×8×8 at 64² it lowered the glossy MSE 1.95 → 1.81× and the perfect trace
            0.99 → 0.82× the black image, at 32² 4.4 → 2.2×), ``"depth_normal"`` (default: those texels
            whose normal also faces as the hit's surface does; 29–45 % below ``"depth_aware"`` on
            ``sponza_comparison``, seed 0) or ``"mip"``
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
        timing_repeats: shading repeats timed (median) after the compile run; 0: not timed (the shading
            runs once, ``shading_s_per_frame`` and ``shading_compile_s`` are None), for runs that measure
            accuracy only (the repeats run the whole glossy trace again: on Sponza at 512 glossy rays a
            pixel, 145 s each).
        progress: progress bars for the reference render.
        backend: who path-traces the reference render and the CRN glossy reference: ``"jax"`` (default)
            or ``"mitsuba"`` (the same model and random numbers in Dr.Jit, several times faster on a CPU;
            ``render.RenderConfig.backend``), or ``"auto"`` (replaced by ``render.resolve_backend``'s
            pick). The exact caster of the primary hits and the perfect trace
            is the ``caster`` argument either way.
    """

    width: int = setting(64, lo=1)
    height: int = setting(64, lo=1)
    spp: int | str = 64  # an int ≥ 1 or "auto" (__post_init__)
    glossy_spp: int = setting(8, lo=1)
    glossy_ref_spp: int | str = 4  # an int ≥ 2 or "auto" (__post_init__)
    noise_target: float = setting(0.05, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    pilot_spp: int = setting(8, lo=2)
    max_spp: int = setting(1024, lo=2)  # and ≥ pilot_spp (__post_init__)
    max_depth: int = setting(8, lo=3)
    shading: str = setting("lightfield", choices=SHADINGS)
    trace: TraceConfig = dataclasses.field(default_factory=TraceConfig)
    glossy_filter: str = setting(DEFAULT_GLOSSY_FILTER, choices=GLOSSY_FILTERS)
    glossy_lod_bias: float = setting(0.0)
    perfect_trace_margin: float = setting(0.05, lo=0.0, hi=1.0, hi_open=True)
    agreement_rtol: float = setting(0.02, lo=0.0)
    bootstrap_resamples: int = setting(1000, lo=1)
    relmse_eps: float = setting(0.01, lo=0.0, lo_open=True)
    seed: int = 0
    normal_bias: float = setting(0.2, lo=0.0)
    leak_sigmas: float = setting(LEAK_SIGMAS, lo=0.0, lo_open=True)
    timing_repeats: int = setting(3, lo=0)
    progress: bool = False
    backend: str = "jax"  # one of render.BACKEND_CHOICES, "auto" resolved (__post_init__)

    def __post_init__(self):
        """The declared ranges and choices (``_core.runtime.check_settings``), then the counts that may be
        ``"auto"``, the cap against the pilot count, the tracer settings and the backend."""
        check_settings(self)
        check_count(self.spp, "EvalConfig.spp")
        check_count(self.glossy_ref_spp, "EvalConfig.glossy_ref_spp", minimum=2)
        # max_spp ≥ pilot_spp (the ranges it checks too are the declared ones)
        check_target(
            "EvalConfig",
            noise_target=self.noise_target,
            pilot_spp=self.pilot_spp,
            max_spp=self.max_spp,
            min_pilot=2,
        )
        if not isinstance(self.trace, TraceConfig):
            raise ConfigError(f"EvalConfig.trace must be a TraceConfig, got {type(self.trace).__name__}")
        from ..render import resolve_backend

        object.__setattr__(self, "backend", resolve_backend(self.backend, "EvalConfig.backend"))


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
