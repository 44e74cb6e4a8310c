"""Evaluate a baked probe set on a scene view (DESIGN.md "Evaluation protocol"; issue 4).

Protocol (docs/evaluate.md):

* **Reference**: the path tracer (``render.render``) at ``spp`` paths per pixel gives every component
  (emission, direct, diffuse indirect, glossy indirect, full) and its per-pixel variance of the mean.
* **Sample counts** ``spp`` and ``glossy_ref_spp`` are fixed ints or ``"auto"``: chosen from a pilot pass
  so that the scored component's noise floor is at most ``noise_target`` × its black-image MSE
  (``_samples.py``); ``samples`` in the metrics says how, and whether the final pass met the target.
* **Primary hits** are exact (the caster), ``glossy_spp`` per pixel, with the reference's own camera
  jitter for pixel sample s (``path_uniforms(seed, pixel, s, 0)``): the probe image sees the same points.
* **Glossy indirect, common random numbers.** For pixel sample s, one GGX visible-normal direction
  wᵢ (from the reference's bounce-1 uniforms, so it is the direction the reference takes when it picks
  the specular lobe) and the specular-lobe estimator w = f_s cos θᵢ / pdf_s. The reference radiance
  along wᵢ is path-traced (``glossy_ref_spp`` paths: reflected = full − emission at x₂); the probe
  radiance is the light-field trace + the baked reflected radiance read at the hit by direction
  (``glossy_filter``: texel, bilinear or footprint-driven MIP; probes/_glossy.py). Both images are
  mean_s(w·L), so the difference measures the probe representation, not the GGX sampling noise.
  Noise floor: the variance of the reference's CRN estimate given the shared directions,
  mean over pixels and channels of Σ_s w_s² Var[L̂_s] / S² (Var from the ``glossy_ref_spp`` paths) —
  the MSE a perfect probe set would reach. ``mse_glossy_indirect_no_crn`` compares the same probe
  image with the reference render's own glossy indirect (independent samples), for contrast.
* **Diffuse indirect**: probe = mean_s(ρ_s · E(x_s, n_s) / π), with E from the selected shading method
  and ρ_s = π f_d(wₒ, wᵢ) for a cosine-sampled wᵢ (the diffuse lobe's directional albedo, Fresnel
  included, estimated with the reference's bounce-1 uniforms); reference = the render's diffuse
  indirect. Noise floor: mean over pixels and channels of the render's variance of the pixel mean.
  ``shading`` selects only this diffuse method; the glossy image always comes from the light-field
  trace (classic irradiance and SH probes have no glossy representation of their own here).
* **Full**: reference emission + direct (exact, shared) + probe diffuse + probe glossy vs the render's
  full image. The shared emission and direct cancel in the difference, so the noise floor is the mean of
  the render's variance of the diffuse- plus glossy-indirect pixel means (their covariance ignored).
* **Light leak**, measured against the reference's own noise (``_decompose.light_leak``): a pixel
  leaks when the probe diffuse indirect exceeds the reference's by more than ``EvalConfig.leak_sigmas`` (4)
  standard errors of the reference pixel mean, in luminance, judged only where that standard error is
  known (positive sample variance; a pixel whose paths all returned 0 is not judged).
  ``light_leak_pixels`` counts the flagged pixels, ``light_leak_judged_pixels`` the judged ones,
  ``light_leak_share`` is their ratio and ``light_leak_energy`` Σ of the excess luminance over the
  flagged pixels / number of pixels. (The earlier definition — probe light on pixels whose reference was
  near 0 — flagged ~30 % of the pixels for every method at low spp.)
* **The glossy error taken apart** (``_decompose.py``): the perfect trace (exact hit, radiance read from
  the probes there: the representation floor) and the trace's share; the MSE split additively by ray
  status (hit / miss / unresolved) and the resolved rays scored apart; agreement of resolved hits with
  the exact distance; the unresolved share also among the rays whose origin one of the K nearest usable
  probes sees (``probes.origins_seen``: the tracer's own visibility test at the origin). Every MSE also
  gets a relative MSE and a 95% bootstrap interval over pixels.

The steps are public (``_steps.py``): ``render_reference``, ``sample_primary``, ``crn_reference``,
``shade_probes``, ``perfect_trace``, then :func:`score`.
"""

from __future__ import annotations

import dataclasses
import logging

import jax
import jax.numpy as jnp
import numpy as np

from .._core import ConfigError, LightFieldProbes, Scene, is_auto, scene_box
from ..probes import TraceStatus, check_bake_settings, glossy_maps, tracer_bytes
from ..render import default_caster, seed_from_key
from ._attribute import probe_error
from ._config import EvalConfig
from ._decompose import (
    STATUS_NAMES,
    glossy_terms,
    hit_agreement,
    light_leak,
    mean_sq_error,
    pixel_means,
    pixel_sq_error,
    relative_mse,
)
from ._metrics import (
    EVAL_COMPONENTS,
    ComponentImages,
    ComponentScores,
    DiffuseScores,
    EvalMetrics,
    GlossyScores,
    RunSettings,
    interval95,
    measure_record,
    metric_key,
)
from ._samples import COUNT_OF, CountChoice, crn_for_target, reference_for_target, samples_metrics
from ._steps import (
    CrnReference,
    PerfectTrace,
    PrimarySamples,
    ProbeShading,
    ReferenceImages,
    perfect_trace,
    sample_primary,
    shade_probes,
)

log = logging.getLogger(__name__)

#: The result's images (:func:`_eval_images`), in order: references, probe images, their errors.
EVAL_IMAGES = (
    "ref_emission", "ref_direct", "ref_diffuse_indirect", "ref_glossy_indirect",
    "ref_glossy_indirect_render", "ref_full", "probe_diffuse_indirect", "probe_glossy_indirect",
    "probe_full", "perfect_trace_glossy_indirect", "ref_glossy_indirect_diffuse_at_hit",
    *(f"error_{c}" for c in EVAL_COMPONENTS),
)  # fmt: skip


@dataclasses.dataclass(frozen=True, init=False)
class EvalResult:
    """``scores``: the metrics (:class:`EvalMetrics`; docs/evaluate.md); ``images``: name → (h, w, 3)
    float32 arrays (``ref_*``, ``probe_*`` per component, ``error_*`` = |probe − ref|,
    ``perfect_trace_glossy_indirect``); ``probe_error``: each probe's share of the diffuse and glossy MSE
    (``_attribute.probe_error``, the arrays of ``probe_error.npz``), or None when not recorded; ``extra``:
    keys recorded beside the evaluation's in ``metrics.json`` (``probeplace evaluate``'s ``bake_samples``).

    :attr:`metrics` is the ``metrics.json`` dict, ``scores.to_json()`` then ``extra``. A result may be made
    from such a dict instead of ``scores`` and ``extra`` (``metrics=``): ``EvalMetrics.from_json`` reads it
    and its other keys become ``extra``; so ``dataclasses.replace(result, metrics={**result.metrics, k: v})``
    adds a key (``metrics`` given wins over the ``scores`` and ``extra`` that ``replace`` passes along).
    """

    scores: EvalMetrics
    images: dict[str, np.ndarray]
    probe_error: dict[str, np.ndarray] | None = None
    extra: dict = dataclasses.field(default_factory=dict)

    def __init__(
        self,
        scores: EvalMetrics | None = None,
        images: dict[str, np.ndarray] | None = None,
        probe_error: dict[str, np.ndarray] | None = None,
        extra: dict | None = None,
        *,
        metrics: dict | None = None,
    ):
        if metrics is not None:
            scores = EvalMetrics.from_json(metrics)
            own = set(scores.to_json())
            extra = {k: v for k, v in metrics.items() if k not in own}
        if not isinstance(scores, EvalMetrics):
            raise TypeError(f"EvalResult: scores must be an EvalMetrics, got {type(scores).__name__}")
        if images is None:
            raise TypeError("EvalResult: images are required")
        object.__setattr__(self, "scores", scores)
        object.__setattr__(self, "images", images)
        object.__setattr__(self, "probe_error", probe_error)
        object.__setattr__(self, "extra", dict(extra or {}))

    @property
    def metrics(self) -> dict:
        """The ``metrics.json`` dict (docs/evaluate.md): ``scores.to_json()``, then ``extra``."""
        return {**self.scores.to_json(), **self.extra}


def memory_bytes(lf: LightFieldProbes, subdivide: int) -> dict:
    """Probe memory as stored (Wang 2019 Table 2 style): total, per probe and by map, in bytes; and the
    light-field tracer's maps per usable probe at ``subdivide`` (``probes.tracer_bytes``)."""
    stored = {"normal": "normal16"}  # two int16 components (_core.maths._packed)
    by_map = {
        name: int(getattr(lf, stored.get(name, name)).nbytes)
        for name in ("radiance", "emission", "normal", "distance", "irradiance", "moments")
    }
    if lf.backface is not None:
        by_map["backface"] = int(lf.backface.nbytes)
    total = sum(by_map.values())
    n = int(lf.pos_world.shape[0])
    tracer = tracer_bytes(1, lf.geometry_res, subdivide)
    return {
        "total": total,
        "per_probe": total / max(n, 1),
        "by_map": by_map,
        "tracer_per_usable_probe": tracer,
    }


def evaluate(
    scene: Scene,
    lf: LightFieldProbes,
    *,
    view: str,
    config: EvalConfig | None = None,
    caster=None,
    key: jax.Array | None = None,
    stage=None,
) -> EvalResult:
    """Render one view with the probes and with the reference; compare per component (module docstring).

    Args:
        scene: the scene the probes were baked in.
        lf: baked probes (``probes.bake_probes`` / ``probes.load_probes``).
        view: name of one of ``scene.views``.
        config: image size, samples, shading method, tracer settings (default ``EvalConfig()``).
        caster: exact ray caster (default ``render.default_caster(scene)``).
        key: PRNG key (default: ``config.seed``).
        stage: called with each step's name before it runs (``"reference"``, ``"primary"``, ``"crn"``,
            ``"shading"``, ``"perfect_trace"``, ``"score"``): ``probeplace evaluate``'s stage messages.

    Returns:
        :class:`EvalResult` with metrics (docs/evaluate.md) and images.

    Raises:
        ConfigError: bad configuration, unknown view or no usable probe.
    """
    config = EvalConfig() if config is None else config
    if not isinstance(config, EvalConfig):
        raise ConfigError(f"config must be an EvalConfig, got {type(config).__name__}")
    try:
        camera = scene.view(view)
    except KeyError as e:
        raise ConfigError(str(e.args[0])) from None
    check_bake_settings(lf, scene_name=scene.name, eval_max_depth=config.max_depth)
    if not bool(jnp.any(lf.active & ~lf.inside)):
        raise ConfigError("the probe set has no usable probe (all inactive or inside geometry)")
    caster = default_caster(scene) if caster is None else caster
    seed = int(seed_from_key(key)) if key is not None else int(config.seed) & 0xFFFFFFFF
    stage = stage or (lambda name: None)

    stage("reference")
    ref, ref_count = reference_for_target(scene, camera, config, seed=seed, caster=caster)
    stage("primary")
    prim = sample_primary(scene, camera, config, seed=seed, caster=caster)
    stage("crn")
    crn, crn_count = crn_for_target(scene, prim, config, seed=seed, caster=caster)
    # from here on the counts are the ones rendered (metrics: spp, glossy_ref_spp)
    config = dataclasses.replace(config, spp=ref_count.spp, glossy_ref_spp=crn_count.spp)
    stage("shading")
    maps = glossy_maps(lf, config.glossy_filter, include_emission=False)  # built once, like a bake
    shading = shade_probes(scene, lf, prim, config, maps=maps)
    stage("perfect_trace")
    perfect = perfect_trace(lf, prim, config, caster=caster, maps=maps)
    stage("score")
    counts = {"diffuse_indirect": ref_count, "glossy_indirect": crn_count}
    return score(scene, lf, view, config, seed, ref, prim, crn, shading, perfect, counts=counts)


def _light_leak(ref_img: dict, ref_var: dict, probe_d, hit_px, sigmas: float) -> dict:
    """The light-leak figures of the diffuse indirect image (module docstring, "Light leak"), as
    :class:`DiffuseScores` fields."""
    ref, var = ref_img["diffuse_indirect"], ref_var["diffuse_indirect"]
    leak = light_leak(ref, var, probe_d, hit_px, sigmas=sigmas)
    n, judged = int(leak["flagged"].sum()), int(leak["judged"].sum())
    return {
        "light_leak_energy": leak["energy"],
        "light_leak_pixels": n,
        "light_leak_judged_pixels": judged,
        "light_leak_share": n / judged if judged else None,
        "light_leak_sigmas": float(sigmas),
    }


def _diffuse_scores(config: EvalConfig, ref_img: dict, ref_var: dict, probe_d, hit_px) -> DiffuseScores:
    """The diffuse indirect image against the render's: MSE, noise floor, black image, relative MSE,
    interval, light leak."""
    return measure_record(
        DiffuseScores,
        _images("diffuse_indirect", probe_d, ref_img["diffuse_indirect"], config),
        noise_floor=float(np.mean(ref_var["diffuse_indirect"])),
        **_light_leak(ref_img, ref_var, probe_d, hit_px, config.leak_sigmas),
    )


def _full_scores(config: EvalConfig, ref_img: dict, ref_var: dict, probe_full) -> ComponentScores:
    """The full image against the render's."""
    return measure_record(
        ComponentScores,
        _images("full", probe_full, ref_img["full"], config),
        # Emission and direct are shared by both images, so only the reference's indirect noise remains.
        noise_floor=float(np.mean(ref_var["diffuse_indirect"] + ref_var["glossy_indirect"])),
    )


def _images(component: str, probe, reference, config: EvalConfig, sq_px=None) -> ComponentImages:
    """A component's images for its measured figures; ``sq_px`` defaults to the images' per-pixel error."""
    sq_px = pixel_sq_error(probe, reference) if sq_px is None else sq_px
    return ComponentImages(
        component, np.asarray(probe, np.float64), np.asarray(reference, np.float64), sq_px, config
    )


def _glossy_scores(scene, config: EvalConfig, prim, crn, shading, perfect, imgs, ref_img) -> GlossyScores:
    """The glossy indirect image against the CRN reference and its error taken apart (``_decompose.py``,
    docs/evaluate.md): noise floor, black image, perfect trace, view dependence, trace share, split by
    ray status, agreement, relative MSEs and bootstrap intervals. ``imgs``: the probe, CRN reference,
    perfect-trace and view-independent images."""
    S = prim.spp
    probe_g, crn_ref_g, perfect_g, view_indep_g = imgs
    H, W = prim.height, prim.width
    st = shading.status
    gl = st >= 0
    n_gl = int(gl.sum())
    terms = glossy_terms(prim.w_glossy, shading.glossy, crn.radiance, perfect.radiance, st, S)
    agree, n_agree = hit_agreement(
        shading.t, perfect.t_exact, st, rtol=config.agreement_rtol, atol=agreement_atol(scene)
    )
    n_exact = int(np.sum(gl & np.isfinite(perfect.t_exact)))
    floor = float(np.mean((prim.w_glossy**2 * crn.var_of_mean).reshape(H * W, S, 3).sum(axis=1) / S**2))
    return measure_record(
        GlossyScores,
        _images("glossy_indirect", probe_g, crn_ref_g, config, sq_px=terms["sq_px"]),
        noise_floor=floor,
        mse_no_crn=mean_sq_error(probe_g, ref_img["glossy_indirect"]),
        glossy_rays=n_gl,
        unresolved_share=float(np.mean(st[gl] == TraceStatus.UNRESOLVED)) if n_gl else 0.0,
        **_seen_shares(st, shading.origin_seen),
        mse_perfect_trace=terms["mse_perfect_trace"],
        # What even exact probes storing view-independent radiance miss: the specular lobe of the surface a
        # glossy ray hits, toward the viewer (the CRN reference without that lobe, _steps.py).
        mse_view_dependence=mean_sq_error(view_indep_g, crn_ref_g),
        mse_trace_share=terms["trace_share"],
        trace_excess=terms["trace_excess"],
        mse_by_status=terms["by_status"],
        mse_resolved_only=terms["resolved_only"],
        mse_converged=terms["converged"],
        glossy_status_share={
            name: (float(np.mean(st[gl] == k)) if n_gl else 0.0) for k, name in STATUS_NAMES.items()
        },
        glossy_hit_agreement=agree,
        glossy_hit_agreement_rays=n_agree,
        perfect_trace_fallbacks=int(np.sum(perfect.fallback)),
        perfect_trace_fallback_share=float(np.sum(perfect.fallback) / n_exact) if n_exact else 0.0,
        relmse_perfect_trace=relative_mse(perfect_g, crn_ref_g, eps=config.relmse_eps),
        ci95_mse_perfect_trace=interval95(config, terms["sq_px_perfect"]),
        ci95_mse_trace_share=interval95(config, terms["sq_px"] - terms["sq_px_perfect"]),
        ci95_mse_converged=(
            None if terms["sq_px_converged"] is None else interval95(config, terms["sq_px_converged"])
        ),
    )


def agreement_atol(scene: Scene) -> float:
    """The absolute part of the hit-agreement tolerance (``EvalConfig.agreement_rtol`` is the relative
    part): 1e-4 of the scene box's diagonal, float32's reach at a scene's far end."""
    lo, hi = scene_box(scene)
    return 1e-4 * float(np.linalg.norm(hi - lo))


def _seen_shares(status: np.ndarray, seen: np.ndarray) -> dict:
    """The share of glossy rays whose origin one of the K nearest usable probes sees
    (``ProbeShading.origin_seen``), and the unresolved share among those rays (None when there are none)."""
    gl = status >= 0
    n_gl, seen_gl = int(gl.sum()), gl & seen
    n_seen = int(seen_gl.sum())
    return {
        "origin_seen_share": n_seen / n_gl if n_gl else 0.0,
        "unresolved_seen_share": float(np.mean(status[seen_gl] == TraceStatus.UNRESOLVED))
        if n_seen
        else None,
    }


def _eval_images(ref_img: dict, probe: dict, crn_ref_g, perfect_g, view_indep_g) -> dict:
    """The result's images: references, probe images (``probe``: component → image) and their errors."""
    images = {
        "ref_emission": ref_img["emission"],
        "ref_direct": ref_img["direct"],
        "ref_diffuse_indirect": ref_img["diffuse_indirect"],
        "ref_glossy_indirect": crn_ref_g.astype(np.float32),
        "ref_glossy_indirect_render": ref_img["glossy_indirect"],
        "ref_full": ref_img["full"],
        "probe_diffuse_indirect": probe["diffuse_indirect"].astype(np.float32),
        "probe_glossy_indirect": probe["glossy_indirect"].astype(np.float32),
        "probe_full": probe["full"].astype(np.float32),
        "perfect_trace_glossy_indirect": perfect_g.astype(np.float32),
        # the reference's glossy with the diffuse lobe only where the glossy ray lands: what probes store
        "ref_glossy_indirect_diffuse_at_hit": view_indep_g.astype(np.float32),
    }
    for c in EVAL_COMPONENTS:
        images[f"error_{c}"] = np.abs(images[f"probe_{c}"] - images[f"ref_{c}"]).astype(np.float32)
    assert tuple(images) == EVAL_IMAGES  # the writer's size bound (_write.evaluation_bytes) counts these
    return images


def _run_settings(
    scene: Scene, lf: LightFieldProbes, view: str, config: EvalConfig, seed: int, prim
) -> RunSettings:
    """What was evaluated and how (scene, view, sizes, samples, tracer, probes)."""
    return RunSettings(
        scene=scene.name,
        view=view,
        width=prim.width,
        height=prim.height,
        spp=config.spp,
        glossy_spp=prim.spp,
        glossy_ref_spp=config.glossy_ref_spp,
        max_depth=config.max_depth,
        shading=config.shading,
        trace_hierarchy=config.trace.hierarchy,
        glossy_filter=config.glossy_filter,
        glossy_lod_bias=config.glossy_lod_bias,
        seed=seed,
        n_probes=int(np.sum(np.asarray(lf.active))),
        n_probes_usable=int(np.sum(np.asarray(lf.active) & ~np.asarray(lf.inside))),
        probe_first_hit_lobes=None if lf.bake is None else lf.bake.first_hit_lobes,
    )


def score(
    scene: Scene,
    lf: LightFieldProbes,
    view: str,
    config: EvalConfig,
    seed: int,
    ref: ReferenceImages,
    prim: PrimarySamples,
    crn: CrnReference,
    shading: ProbeShading,
    perfect: PerfectTrace,
    *,
    counts: dict[str, CountChoice] | None = None,
) -> EvalResult:
    """Images and metrics (:class:`EvalMetrics`, docs/evaluate.md) from the steps' results. ``counts``:
    how the reference's counts were chosen (``evaluate`` passes them; ``None``: the fixed counts of
    ``config``), for the ``samples`` group."""
    if counts is None:
        if is_auto(config.spp) or is_auto(config.glossy_ref_spp):
            raise ConfigError("score: config's counts are 'auto'; pass the counts the steps rendered with")
        counts = {c: CountChoice(spp=getattr(config, k), chosen_by="fixed") for c, k in COUNT_OF.items()}
    W, H, S = prim.width, prim.height, prim.spp
    ref_img, ref_var = ref.images, ref.variance
    w_gl = prim.w_glossy
    img = lambda v: pixel_means(v, H * W, S).reshape(H, W, *v.shape[1:])
    probe_g = img(w_gl * shading.glossy)
    crn_ref_g = img(w_gl * crn.radiance)
    perfect_g = img(w_gl * perfect.radiance)
    view_indep_g = img(w_gl * crn.diffuse_at_hit)
    probe_d = img(prim.rho_d * shading.irradiance / np.pi)
    probe_full = ref_img["emission"] + ref_img["direct"] + probe_d + probe_g
    hit_px = img(prim.valid[:, None].astype(np.float64))[..., 0] > 0
    probe = {"diffuse_indirect": probe_d, "glossy_indirect": probe_g, "full": probe_full}
    images = _eval_images(ref_img, probe, crn_ref_g, perfect_g, view_indep_g)

    diffuse = _diffuse_scores(config, ref_img, ref_var, probe_d, hit_px)
    glossy = _glossy_scores(
        scene, config, prim, crn, shading, perfect, (probe_g, crn_ref_g, perfect_g, view_indep_g), ref_img
    )
    samples = samples_metrics(config, counts, {"diffuse_indirect": diffuse, "glossy_indirect": glossy})
    scores = EvalMetrics(
        settings=_run_settings(scene, lf, view, config, seed, prim),
        diffuse_indirect=diffuse,
        glossy_indirect=glossy,
        full=_full_scores(config, ref_img, ref_var, probe_full),
        bootstrap_resamples=config.bootstrap_resamples,
        relmse_eps=config.relmse_eps,
        shading_s_per_frame=shading.seconds_per_frame,
        shading_compile_s=shading.compile_seconds,
        reference_s=ref.seconds,
        memory_bytes=memory_bytes(lf, config.trace.subdivide),
        samples=samples,
    )
    chosen = any(c.chosen_by == "target" for c in counts.values())
    if chosen and not samples.target_met:  # fixed counts were asked for: no warning
        ratios = ", ".join(
            f"{c} {v:.3g}" if v is not None else f"{c} n/a (black MSE 0)"
            for c, v in samples.floor_over_black.items()
        )
        log.warning(
            "reference noise floor ÷ black MSE: %s; above the noise target %g (metrics.json: samples)",
            ratios,
            config.noise_target,
        )
    shares = probe_error(lf.pos_world, prim, shading, probe_d, ref_img["diffuse_indirect"], crn.radiance)
    if shares is not None:
        for c in ("diffuse_indirect", "glossy_indirect"):
            shares[metric_key("mse", c)] = np.asarray(scores.component(c).mse, np.float64)
    return EvalResult(scores=scores, images=images, probe_error=shares)
