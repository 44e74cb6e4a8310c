"""Evaluate a baked probe set on a scene view (DESIGN.md "Evaluation protocol"; issue 4).

Protocol (docs/evaluate.md):

* **Reference**: the path tracer (``render.render``) at ``spp`` paths per pixel gives every component
  (emission, direct, diffuse indirect, glossy indirect, full) and its per-pixel variance of the mean.
* **Primary hits** are exact (the caster), ``glossy_spp`` per pixel, with the reference's own camera
  jitter for pixel sample s (``path_uniforms(seed, pixel, s, 0)``): the probe image sees the same points.
* **Glossy indirect, common random numbers.** For pixel sample s, one GGX visible-normal direction
  wᵢ (from the reference's bounce-1 uniforms, so it is the direction the reference takes when it picks
  the specular lobe) and the specular-lobe estimator w = f_s cos θᵢ / pdf_s. The reference radiance
  along wᵢ is path-traced (``glossy_ref_spp`` paths: reflected = full − emission at x₂); the probe
  radiance is the light-field trace + the baked reflected radiance at the hit texel. Both images are
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
* **Light leak**: the diffuse-indirect energy the probes put on pixels whose reference diffuse indirect
  is ~0 (luminance ≤ ``leak_threshold`` × the image's mean reference diffuse-indirect luminance):
  Σ over those pixels of the probe's diffuse-indirect luminance / number of pixels.
"""

from __future__ import annotations

import dataclasses
import statistics
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._core import ConfigError, LightFieldProbes, Scene, luminance
from ..probes._shade import SHADINGS, glossy_radiance, sh_coefficients, shade_irradiance
from ..probes._trace import RAY_UNRESOLVED, TraceConfig, make_tracer
from ..render import (
    BrdfParams,
    RenderConfig,
    camera_rays,
    default_caster,
    eval_brdf,
    make_frame,
    path_uniforms,
    pdf_brdf,
    render,
    sample_ggx_vndf,
    seed_from_key,
    to_local,
    to_world,
    trace_rays,
)
from ..render._integrator import RAY_EPS
from ..render._sampling import sample_cosine_hemisphere

EVAL_COMPONENTS = ("diffuse_indirect", "glossy_indirect", "full")


@dataclasses.dataclass(frozen=True, kw_only=True)
class EvalConfig:
    """Evaluation settings.

    Attributes:
        width, height: image size.
        spp: reference paths per pixel (the render of every component).
        glossy_spp: primary samples per pixel for the probe image, each with one GGX direction (CRN).
        glossy_ref_spp: paths per GGX direction for the CRN reference (≥ 2, for its variance).
        max_depth: longest path in segments (≥ 3: indirect light needs two bounces).
        shading: diffuse method, ``"lightfield"`` | ``"irradiance"`` | ``"sh"``.
        trace: light-field tracer settings (glossy rays).
        seed: random seed (used when no key is given).
        normal_bias: Chebyshev receiver offset (× probe spacing), see ``probes.diffuse_irradiance``.
        leak_threshold: relative luminance below which a reference pixel counts as unlit (light leak).
        timing_repeats: shading repeats timed (median) after the compile run.
        progress: progress bars for the reference render.
    """

    width: int = 64
    height: int = 64
    spp: int = 64
    glossy_spp: int = 8
    glossy_ref_spp: int = 4
    max_depth: int = 8
    shading: str = "lightfield"
    trace: TraceConfig = dataclasses.field(default_factory=TraceConfig)
    seed: int = 0
    normal_bias: float = 0.2
    leak_threshold: float = 0.01
    timing_repeats: int = 3
    progress: bool = False

    def __post_init__(self):
        for name in ("width", "height", "spp", "glossy_spp", "timing_repeats"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ConfigError(f"EvalConfig.{name} must be a positive int, got {v!r}")
        if not isinstance(self.glossy_ref_spp, int) or self.glossy_ref_spp < 2:
            raise ConfigError(f"EvalConfig.glossy_ref_spp must be an int ≥ 2, got {self.glossy_ref_spp!r}")
        if not isinstance(self.max_depth, int) or self.max_depth < 3:
            raise ConfigError(f"EvalConfig.max_depth must be an int ≥ 3, got {self.max_depth!r}")
        if self.shading not in SHADINGS:
            raise ConfigError(f"EvalConfig.shading must be one of {SHADINGS}, got {self.shading!r}")
        if not isinstance(self.trace, TraceConfig):
            raise ConfigError(f"EvalConfig.trace must be a TraceConfig, got {type(self.trace).__name__}")
        if not self.normal_bias >= 0 or not self.leak_threshold >= 0:
            raise ConfigError("EvalConfig.normal_bias and leak_threshold must be ≥ 0")


@dataclasses.dataclass(frozen=True)
class EvalResult:
    """``metrics``: JSON-ready dict (docs/evaluate.md); ``images``: name → (h, w, 3) float32 arrays
    (``ref_*``, ``probe_*`` per component, ``error_*`` = |probe − ref|)."""

    metrics: dict
    images: dict[str, np.ndarray]


class _Samples(eqx.Module):
    """Per primary sample: shading point, oriented normal, spawn origin, GGX direction and weight,
    diffuse-albedo sample and validity."""

    x: Float[Array, "n 3"]
    n: Float[Array, "n 3"]
    origin: Float[Array, "n 3"]
    wi: Float[Array, "n 3"]
    w_glossy: Float[Array, "n 3"]
    rho_d: Float[Array, "n 3"]
    valid: Array


def _sample_one(mats, specular, offset_len, o, d, t, tri, ng, ns, mat, u1):
    hit = tri >= 0
    x = o + jnp.where(hit, t, 0.0) * d
    wo = -d
    flip = jnp.where(jnp.dot(ng, wo) < 0, -1.0, 1.0)
    ng_f, ns_f = ng * flip, ns * flip
    tb, bb = make_frame(ns_f)
    wo_l = to_local(wo, tb, bb, ns_f)
    m = jnp.maximum(mat, 0)
    p = BrdfParams(
        base_color=mats.base_color[m],
        roughness=mats.roughness[m],
        metallic=mats.metallic[m],
        specular=specular,
    )
    alpha = jnp.maximum(p.roughness * p.roughness, 1e-3)
    wo_up = jnp.where(wo_l[2] > 0, wo_l, jnp.asarray([0.0, 0.0, 1.0], wo_l.dtype))
    h = sample_ggx_vndf(wo_up, alpha, u1[1:3])
    wi_l = 2.0 * jnp.dot(wo_l, h) * h - wo_l
    wi_l = wi_l / jnp.maximum(jnp.linalg.norm(wi_l), 1e-12)
    _, f_s = eval_brdf(p, wo_l, wi_l)
    _, pdf_s, _ = pdf_brdf(p, wo_l, wi_l)
    ok = hit & (wo_l[2] > 0) & (pdf_s > 0) & (wi_l[2] > 0)
    w = jnp.where(ok, f_s * wi_l[2] / jnp.where(ok, pdf_s, 1.0), 0.0)
    wi = to_world(wi_l, tb, bb, ns_f)
    ok = ok & (jnp.dot(wi, ng_f) > 0)
    w = jnp.where(ok, w, 0.0)
    wd = sample_cosine_hemisphere(u1[1:3])
    f_d, _ = eval_brdf(p, wo_l, wd)
    rho = jnp.where(hit & (wo_l[2] > 0), jnp.pi * f_d, 0.0)
    origin = x + jnp.maximum((1.0 + jnp.max(jnp.abs(x))) * RAY_EPS, offset_len) * ng_f
    return x, ns_f, origin, wi, w, rho, hit & (wo_l[2] > 0)


@eqx.filter_jit
def _samples(mats, specular, offset_len, o, d, hit, u1) -> _Samples:
    out = jax.vmap(_sample_one, in_axes=(None, None, None, 0, 0, 0, 0, 0, 0, 0, 0))(
        mats, specular, offset_len, o, d, hit.t, hit.tri, hit.geo_normal, hit.shading_normal, hit.material, u1
    )
    return _Samples(*out)


def memory_bytes(lf: LightFieldProbes) -> dict:
    """Probe memory as stored (Wang 2019 Table 2 style): total, per probe and by map, in bytes."""
    by_map = {
        name: int(np.asarray(getattr(lf, name)).nbytes)
        for name in ("radiance", "emission", "normal", "distance", "irradiance", "moments")
    }
    by_map["mips"] = int(sum(np.asarray(a).nbytes for a in (*lf.distance_min_mips, *lf.distance_max_mips)))
    total = sum(by_map.values())
    n = int(lf.pos_world.shape[0])
    return {"total": total, "per_probe": total / max(n, 1), "by_map": by_map}


def _mse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))


def _per_pixel(v: np.ndarray, h: int, w: int, s: int) -> np.ndarray:
    return v.reshape(h * w, s, *v.shape[1:]).mean(axis=1).reshape(h, w, *v.shape[1:])


def evaluate(
    scene: Scene,
    lf: LightFieldProbes,
    *,
    view: str,
    config: EvalConfig = EvalConfig(),
    caster=None,
    key: jax.Array | None = None,
) -> EvalResult:
    """Render one view with the probes and with the reference; compare per component (module docstring).

    Args:
        scene: the scene the probes were baked in.
        lf: baked probes (``probes.bake_probes`` / ``probes.load_probes``).
        view: name of one of ``scene.views``.
        config: image size, samples, shading method, tracer settings.
        caster: exact ray caster (default ``render.default_caster(scene)``).
        key: PRNG key (default: ``config.seed``).

    Returns:
        :class:`EvalResult` with metrics (docs/evaluate.md) and images.

    Raises:
        ConfigError: bad configuration, unknown view or no usable probe.
    """
    if not isinstance(config, EvalConfig):
        raise ConfigError(f"config must be an EvalConfig, got {type(config).__name__}")
    try:
        camera = scene.view(view)
    except KeyError as e:
        raise ConfigError(str(e.args[0])) from None
    if not bool(jnp.any(lf.active & ~lf.inside)):
        raise ConfigError("the probe set has no usable probe (all inactive or inside geometry)")
    caster = default_caster(scene) if caster is None else caster
    seed = int(seed_from_key(key)) if key is not None else int(config.seed) & 0xFFFFFFFF
    seed_u = jnp.asarray(seed, jnp.uint32)
    W, H, S = config.width, config.height, config.glossy_spp

    # ---- reference render (all components, variance of the mean)
    t0 = time.perf_counter()
    ref = render(
        scene,
        camera,
        RenderConfig(width=W, height=H, spp=config.spp, max_depth=config.max_depth, progress=config.progress),
        key=seed_u,
        caster=caster,
    )
    reference_s = time.perf_counter() - t0
    ref_img = {c: np.asarray(ref.image(c), np.float32) for c in ref.components}
    ref_var = {c: np.asarray(ref.variance(c), np.float64) for c in ref.components}

    # ---- primary samples (the reference's jitter and bounce-1 uniforms: common random numbers)
    pix = jnp.repeat(jnp.arange(W * H, dtype=jnp.int32), S)
    smp = jnp.tile(jnp.arange(S, dtype=jnp.int32), W * H)
    pu = jax.jit(jax.vmap(path_uniforms, in_axes=(None, 0, 0, None)), static_argnums=3)
    u0 = pu(seed_u, pix, smp, 0)
    u1 = pu(seed_u, pix, smp, 1)
    o, d = camera_rays(camera, W, H, pix, u0[:, 1:3])
    hit = caster.closest_hit(o, d)
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    offset_len = jnp.asarray(1e-4 * float(np.linalg.norm(hi - lo)), jnp.float32)
    smp_ = _samples(scene.materials, jnp.float32(1.0), offset_len, o, d, hit, u1)
    valid = np.asarray(smp_.valid)
    w_gl = np.asarray(smp_.w_glossy, np.float64)
    g_idx = np.flatnonzero(valid & (np.max(w_gl, axis=1) > 0))

    # ---- CRN reference along the GGX directions
    go, gd = smp_.origin[g_idx], smp_.wi[g_idx]
    L_ref = np.zeros((len(pix), 3))
    V_ref = np.zeros((len(pix), 3))
    if len(g_idx):
        rr = trace_rays(
            scene,
            go,
            gd,
            spp=config.glossy_ref_spp,
            key=jnp.asarray((seed + 0x9E3779B9) & 0xFFFFFFFF, jnp.uint32),
            max_depth=config.max_depth - 1,
            caster=caster,
            progress=config.progress,
        )
        L_ref[g_idx] = np.asarray(rr.component("full"), np.float64) - np.asarray(
            rr.component("emission"), np.float64
        )
        V_ref[g_idx] = np.asarray(rr.var_of_mean[:, rr.components.index("full")], np.float64)

    # ---- probe shading (timed: compile apart, median of repeats)
    tracer = make_tracer(lf, scene.bounds, config=config.trace)
    xs, ns = smp_.x, smp_.n
    sh_c = sh_coefficients(lf) if config.shading == "sh" else None  # baked once, like the maps

    def shade():
        e = shade_irradiance(
            lf,
            xs,
            ns,
            method=config.shading,
            index=tracer.index,
            **({"normal_bias": config.normal_bias} if config.shading != "sh" else {"coeffs": sh_c}),
        )
        if len(g_idx):
            lg, st = glossy_radiance(tracer, lf, go, gd, include_emission=False)
        else:
            lg, st = jnp.zeros((0, 3), jnp.float32), jnp.zeros((0,), jnp.int32)
        return jax.block_until_ready((e, lg, st))

    t0 = time.perf_counter()
    E, L_pr_g, status = shade()
    first_s = time.perf_counter() - t0
    times = []
    for _ in range(config.timing_repeats):
        t0 = time.perf_counter()
        shade()
        times.append(time.perf_counter() - t0)
    shading_s = statistics.median(times)

    L_pr = np.zeros((len(pix), 3))
    L_pr[g_idx] = np.asarray(L_pr_g, np.float64)
    E = np.where(valid[:, None], np.asarray(E, np.float64), 0.0)
    rho = np.asarray(smp_.rho_d, np.float64)

    probe_g = _per_pixel(w_gl * L_pr, H, W, S)
    crn_ref_g = _per_pixel(w_gl * L_ref, H, W, S)
    floor_g = float(np.mean((w_gl**2 * V_ref).reshape(H * W, S, 3).sum(axis=1) / S**2))
    probe_d = _per_pixel(rho * E / np.pi, H, W, S)
    probe_full = ref_img["emission"] + ref_img["direct"] + probe_d + probe_g

    # ---- light leak: probe diffuse energy on pixels the reference leaves unlit
    ref_lum = np.asarray(luminance(jnp.asarray(ref_img["diffuse_indirect"], jnp.float32)), np.float64)
    pr_lum = np.asarray(luminance(jnp.asarray(probe_d, jnp.float32)), np.float64)
    hit_px = _per_pixel(valid[:, None].astype(np.float64), H, W, S)[..., 0] > 0
    dark = hit_px & (
        ref_lum <= config.leak_threshold * max(float(ref_lum[hit_px].mean()) if hit_px.any() else 0, 0)
    )
    leak = float(np.sum(np.where(dark, pr_lum, 0.0)) / (H * W))

    st = np.asarray(status)
    images = {
        "ref_emission": ref_img["emission"],
        "ref_direct": ref_img["direct"],
        "ref_diffuse_indirect": ref_img["diffuse_indirect"],
        "ref_glossy_indirect": crn_ref_g.astype(np.float32),
        "ref_glossy_indirect_render": ref_img["glossy_indirect"],
        "ref_full": ref_img["full"],
        "probe_diffuse_indirect": probe_d.astype(np.float32),
        "probe_glossy_indirect": probe_g.astype(np.float32),
        "probe_full": probe_full.astype(np.float32),
    }
    for c in EVAL_COMPONENTS:
        images[f"error_{c}"] = np.abs(images[f"probe_{c}"] - images[f"ref_{c}"]).astype(np.float32)
    metrics = {
        "scene": scene.name,
        "view": view,
        "width": W,
        "height": H,
        "spp": config.spp,
        "glossy_spp": S,
        "glossy_ref_spp": config.glossy_ref_spp,
        "max_depth": config.max_depth,
        "shading": config.shading,
        "trace_hierarchy": config.trace.hierarchy,
        "seed": seed,
        "n_probes": int(np.sum(np.asarray(lf.active))),
        "n_probes_usable": int(np.sum(np.asarray(lf.active) & ~np.asarray(lf.inside))),
        "mse_glossy_indirect": _mse(probe_g, crn_ref_g),
        "noise_floor_glossy_indirect": floor_g,
        "mse_glossy_indirect_no_crn": _mse(probe_g, ref_img["glossy_indirect"]),
        "mse_diffuse_indirect": _mse(probe_d, ref_img["diffuse_indirect"]),
        # A black image (no indirect light at all) against the same references: a method above this adds
        # more wrong light (leaks, self-hits) than it recovers.
        "mse_black_glossy_indirect": _mse(np.zeros_like(crn_ref_g), crn_ref_g),
        "mse_black_diffuse_indirect": _mse(
            np.zeros_like(ref_img["diffuse_indirect"]), ref_img["diffuse_indirect"]
        ),
        "noise_floor_diffuse_indirect": float(np.mean(ref_var["diffuse_indirect"])),
        "mse_full": _mse(probe_full, ref_img["full"]),
        # Emission and direct are shared by both images, so only the reference's indirect noise remains.
        "noise_floor_full": float(np.mean(ref_var["diffuse_indirect"] + ref_var["glossy_indirect"])),
        "light_leak_energy": leak,
        "light_leak_pixels": int(dark.sum()),
        "glossy_rays": len(g_idx),
        "unresolved_share": float(np.mean(st == RAY_UNRESOLVED)) if len(st) else 0.0,
        "shading_s_per_frame": shading_s,
        "shading_compile_s": max(first_s - shading_s, 0.0),
        "reference_s": reference_s,
        "memory_bytes": memory_bytes(lf),
    }
    return EvalResult(metrics=metrics, images=images)
