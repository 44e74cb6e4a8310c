"""The steps of :func:`~probeplace.evaluate.evaluate`, callable one by one (diagnostics, benchmarks).

``render_reference`` → ``sample_primary`` → ``crn_reference`` → ``shade_probes`` → ``perfect_trace`` →
``evaluate.score``; each returns a typed, host-side (NumPy) result. Samples are pixel-major: sample
i = pixel · S + s, S = ``config.glossy_spp``; "glossy samples" are those with a glossy ray (a valid
primary hit and a non-zero specular weight), ``PrimarySamples.glossy_idx``.
"""

from __future__ import annotations

import dataclasses
import statistics
import time
from functools import partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._core import Camera, LightFieldProbes, Scene, scene_box
from ..probes import (
    bake_depth_for,
    glossy_maps,
    glossy_trace,
    irradiance_weights,
    make_tracer,
    origins_seen,
    perfect_trace_radiance,
    sh_coefficients,
    shade_irradiance,
)
from ..render import (
    RAY_EPS,
    BrdfParams,
    RenderConfig,
    camera_rays,
    eval_brdf,
    make_frame,
    path_uniforms,
    pdf_brdf,
    render,
    sample_cosine_hemisphere,
    sample_ggx_vndf,
    to_local,
    to_world,
    trace_rays,
)
from ._config import EvalConfig

#: Status of samples without a glossy ray.
NO_RAY = -1


@dataclasses.dataclass(frozen=True)
class ReferenceImages:
    """The reference render: component → (h, w, 3) float32 image and float64 variance of the pixel
    mean; ``seconds``: wall time."""

    images: dict[str, np.ndarray]
    variance: dict[str, np.ndarray]
    seconds: float


@dataclasses.dataclass(frozen=True)
class PrimarySamples:
    """Per primary sample (n = width·height·spp): shading point ``x`` and normal ``n`` (JAX, for the
    diffuse lookups), validity, glossy weight w = f_s cos θ / pdf_s (0: no glossy ray) and diffuse
    albedo sample ρ (NumPy float64); per glossy sample: ray origin, direction and footprint cone
    Ω = 1 / (spp · pdf_s) in sr (probes/_glossy.py)."""

    width: int
    height: int
    spp: int
    x: Float[Array, "n 3"]
    n: Float[Array, "n 3"]
    valid: np.ndarray
    w_glossy: np.ndarray
    rho_d: np.ndarray
    glossy_idx: np.ndarray
    origins: Float[Array, "g 3"]
    directions: Float[Array, "g 3"]
    cone: Float[Array, " g"]

    @property
    def n_samples(self) -> int:
        return int(self.valid.shape[0])


@dataclasses.dataclass(frozen=True)
class CrnReference:
    """Per sample: the path-traced reflected radiance along its glossy ray and its variance of the mean
    (zeros for samples without one); ``diffuse_at_hit``: the same with the surface the glossy ray hits
    reflecting by its diffuse lobe only — what a probe texel stores (``probes.path_traced_radiance``),
    so ``radiance − diffuse_at_hit`` is the view-dependent part no probe can hand on."""

    radiance: np.ndarray
    var_of_mean: np.ndarray
    diffuse_at_hit: np.ndarray


@dataclasses.dataclass(frozen=True)
class ProbeShading:
    """Per sample: irradiance E (zeros where invalid), glossy radiance, tracer status (``NO_RAY`` where
    there is no glossy ray), light-field hit distance and MIP level, whether its glossy ray's origin is
    seen by one of the K nearest usable probes (``probes.origins_seen``; False without a ray); shading
    time per frame (median of repeats) and compile time (first run − median). Which probes shaded each
    sample (``None`` when not recorded): ``probe``, the probe whose radiance the glossy read used
    (``GlossyResult.probe``: the resolving probe of a hit, the nearest usable probe of an unresolved ray;
    -1 on a miss or without a ray); ``diffuse_ids`` / ``diffuse_weights``, (n, k) the probes the diffuse
    irradiance blended and their normalised weights (``probes.irradiance_weights``; id -1, weight 0 in an
    unused slot and for invalid samples)."""

    irradiance: np.ndarray
    glossy: np.ndarray
    status: np.ndarray
    t: np.ndarray
    lod: np.ndarray
    origin_seen: np.ndarray
    seconds_per_frame: float | None
    compile_seconds: float | None
    probe: np.ndarray | None = None
    diffuse_ids: np.ndarray | None = None
    diffuse_weights: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class PerfectTrace:
    """Per sample: radiance read from the probes at the exact hit of its glossy ray, the exact distance
    (inf: a miss or no ray) and whether no probe saw the hit (nearest-probe fallback)."""

    radiance: np.ndarray
    t_exact: np.ndarray
    fallback: np.ndarray


def render_reference(
    scene: Scene, camera: Camera, config: EvalConfig, *, seed: int, caster
) -> ReferenceImages:
    """The path-traced reference of every component (``render.render``, ``config.spp`` paths/pixel)."""
    t0 = time.perf_counter()
    cfg = RenderConfig(
        width=config.width,
        height=config.height,
        spp=config.spp,
        max_depth=config.max_depth,
        progress=config.progress,
        backend=config.backend,
    )
    caster = caster if config.backend == "jax" else None  # Mitsuba casts its own rays
    ref = render(scene, camera, cfg, key=jnp.asarray(seed, jnp.uint32), caster=caster)
    images = {c: np.asarray(ref.image(c), np.float32) for c in ref.components}
    variance = {c: np.asarray(ref.variance(c), np.float64) for c in ref.components}
    return ReferenceImages(images, variance, time.perf_counter() - t0)


class _Samples(eqx.Module):
    x: Float[Array, "n 3"]
    n: Float[Array, "n 3"]
    origin: Float[Array, "n 3"]
    wi: Float[Array, "n 3"]
    w_glossy: Float[Array, "n 3"]
    pdf_glossy: Float[Array, " n"]
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
    return x, ns_f, origin, wi, w, pdf_s, rho, hit & (wo_l[2] > 0)


# Built once at import: a jit of a fresh vmap inside the function traced and compiled again every call.
_pixel_uniforms = jax.jit(jax.vmap(path_uniforms, in_axes=(None, 0, 0, None)), static_argnums=3)


@partial(jax.jit, static_argnums=(2, 3, 4))  # one program, not one per operation (issue 32)
def _primary_rays(camera, seed_u, W: int, H: int, S: int):
    """Camera rays of every (pixel, sample) with the reference's jitter (bounce-0 uniforms 1–2) and the
    bounce-1 uniforms, pixel-major."""
    pix = jnp.repeat(jnp.arange(W * H, dtype=jnp.int32), S)
    smp = jnp.tile(jnp.arange(S, dtype=jnp.int32), W * H)
    u0 = _pixel_uniforms(seed_u, pix, smp, 0)
    u1 = _pixel_uniforms(seed_u, pix, smp, 1)
    o, d = camera_rays(camera, W, H, pix, u0[:, 1:3])
    return o, d, u1


@eqx.filter_jit
def _samples(mats, specular, offset_len, o, d, hit, u1) -> _Samples:
    out = jax.vmap(_sample_one, in_axes=(None, None, None, 0, 0, 0, 0, 0, 0, 0, 0))(
        mats, specular, offset_len, o, d, hit.t, hit.tri, hit.geo_normal, hit.shading_normal, hit.material, u1
    )
    return _Samples(*out)


def sample_primary(scene: Scene, camera: Camera, config: EvalConfig, *, seed: int, caster) -> PrimarySamples:
    """Exact primary hits with the reference's own camera jitter and bounce-1 uniforms (common random
    numbers): for pixel sample s, ``path_uniforms(seed, pixel, s, 0 | 1)``; one GGX visible-normal
    direction and one cosine direction (for the diffuse albedo) per sample."""
    W, H, S = config.width, config.height, config.glossy_spp
    o, d, u1 = _primary_rays(camera, jnp.asarray(seed, jnp.uint32), W, H, S)
    hit = caster.closest_hit(o, d)
    lo, hi = scene_box(scene)
    offset_len = jnp.asarray(1e-4 * float(np.linalg.norm(hi - lo)), jnp.float32)
    s = _samples(scene.materials, jnp.float32(1.0), offset_len, o, d, hit, u1)
    valid = np.asarray(s.valid)
    w_gl = np.asarray(s.w_glossy, np.float64)
    g_idx = np.flatnonzero(valid & (np.max(w_gl, axis=1) > 0))
    pdf = np.asarray(s.pdf_glossy, np.float64)[g_idx]
    cone = jnp.asarray(1.0 / (S * np.maximum(pdf, 1e-30)), jnp.float32)
    return PrimarySamples(
        width=W,
        height=H,
        spp=S,
        x=s.x,
        n=s.n,
        valid=valid,
        w_glossy=w_gl,
        rho_d=np.asarray(s.rho_d, np.float64),
        glossy_idx=g_idx,
        origins=s.origin[g_idx],
        directions=s.wi[g_idx],
        cone=cone,
    )


def crn_reference(
    scene: Scene, prim: PrimarySamples, config: EvalConfig, *, seed: int, caster
) -> CrnReference:
    """Reflected radiance along each glossy ray, path traced (``glossy_ref_spp`` paths, ``max_depth − 1``
    segments; reflected = full − emission at the next hit), with every lobe and with the diffuse lobe
    only at the surface the ray hits (:class:`CrnReference`)."""
    L, V, Ld = (np.zeros((prim.n_samples, 3)) for _ in range(3))
    if len(prim.glossy_idx):
        rr = trace_rays(
            scene,
            prim.origins,
            prim.directions,
            spp=config.glossy_ref_spp,
            key=jnp.asarray((seed + 0x9E3779B9) & 0xFFFFFFFF, jnp.uint32),
            max_depth=bake_depth_for(config.max_depth),  # the probes' depth: one rule for both
            caster=caster if config.backend == "jax" else None,
            backend=config.backend,
            progress=config.progress,
        )
        c = {k: np.asarray(rr.component(k), np.float64) for k in rr.components}
        L[prim.glossy_idx] = c["full"] - c["emission"]
        V[prim.glossy_idx] = np.asarray(rr.var_of_mean[:, rr.components.index("full")], np.float64)
        # the same paths, the specular lobe at the hit left out (render._integrator "glossy_direct")
        Ld[prim.glossy_idx] = c["direct"] - c["glossy_direct"] + c["diffuse_indirect"]
    return CrnReference(L, V, Ld)


def shade_probes(
    scene: Scene, lf: LightFieldProbes, prim: PrimarySamples, config: EvalConfig, *, maps=None
) -> ProbeShading:
    """Probe shading of every sample: diffuse irradiance by ``config.shading`` and the glossy rays through
    the light-field tracer, read with ``config.glossy_filter``. Timed: the first run (compile) apart, then
    the median of ``timing_repeats`` runs (both times None when it is 0: one run, not timed). The SH
    coefficients and the glossy read's maps are built once before (like the baked maps); ``maps``:
    :func:`probes.glossy_maps` of ``lf`` (reflected radiance, ``config.glossy_filter``) if already built.
    Untimed, with the same tracer: whether each glossy ray's origin is seen by one of the K nearest usable
    probes (``probes.origins_seen``)."""
    tracer = make_tracer(lf, scene.bounds, config=config.trace)
    sh_c = sh_coefficients(lf) if config.shading == "sh" else None
    maps = glossy_maps(lf, config.glossy_filter, include_emission=False) if maps is None else maps
    g = len(prim.glossy_idx)

    def shade():
        kw = {"normal_bias": config.normal_bias} if config.shading != "sh" else {"coeffs": sh_c}
        e = shade_irradiance(lf, prim.x, prim.n, method=config.shading, index=tracer.index, **kw)
        res = None
        if g:
            res = glossy_trace(
                tracer,
                lf,
                prim.origins,
                prim.directions,
                cone=prim.cone,
                filter=config.glossy_filter,
                lod_bias=config.glossy_lod_bias,
                include_emission=False,
                maps=maps,
            )
        return jax.block_until_ready((e, res))

    t0 = time.perf_counter()
    E, res = shade()
    first = time.perf_counter() - t0
    times = []
    for _ in range(config.timing_repeats):
        t0 = time.perf_counter()
        shade()
        times.append(time.perf_counter() - t0)
    per_frame = statistics.median(times) if times else None
    compile_s = None if per_frame is None else max(first - per_frame, 0.0)
    n = prim.n_samples
    glossy, status = np.zeros((n, 3)), np.full(n, NO_RAY, np.int32)
    t, lod, seen = np.full(n, np.inf), np.zeros(n), np.zeros(n, bool)
    probe = np.full(n, -1, np.int32)
    if g:
        gi = prim.glossy_idx
        glossy[gi] = np.asarray(res.radiance, np.float64)
        status[gi] = np.asarray(res.status)
        t[gi] = np.asarray(res.t, np.float64)
        lod[gi] = np.asarray(res.lod, np.float64)
        probe[gi] = np.asarray(res.probe)
        seen[gi] = np.asarray(origins_seen(tracer, prim.origins))
    E = np.where(prim.valid[:, None], np.asarray(E, np.float64), 0.0)
    # Untimed: which probes the diffuse shading blended (the same weights, probes.irradiance_weights).
    ids, w = irradiance_weights(
        lf, prim.x, prim.n, method=config.shading, index=tracer.index, normal_bias=config.normal_bias
    )
    ids = np.where(prim.valid[:, None], ids, -1).astype(np.int32)
    w = np.where(prim.valid[:, None], np.asarray(w, np.float64), 0.0)
    return ProbeShading(E, glossy, status, t, lod, seen, per_frame, compile_s, probe, ids, w)


def perfect_trace(
    lf: LightFieldProbes, prim: PrimarySamples, config: EvalConfig, *, caster, maps=None
) -> PerfectTrace:
    """The glossy rays with a perfect trace: the exact hit (``caster.closest_hit``), radiance read from the
    probes there (``probes.perfect_trace_radiance``, same filter and footprint as the light-field read)."""
    n = prim.n_samples
    L, t, fb = np.zeros((n, 3)), np.full(n, np.inf), np.zeros(n, bool)
    if len(prim.glossy_idx):
        h = caster.closest_hit(prim.origins, prim.directions)
        te = jnp.where(h.tri >= 0, h.t, jnp.inf)
        maps = glossy_maps(lf, config.glossy_filter, include_emission=False) if maps is None else maps
        r = perfect_trace_radiance(
            lf,
            prim.origins,
            prim.directions,
            te,
            h.geo_normal,
            cone=prim.cone,
            filter=config.glossy_filter,
            lod_bias=config.glossy_lod_bias,
            margin=config.perfect_trace_margin,
            maps=maps,
        )
        gi = prim.glossy_idx
        L[gi] = np.asarray(r.radiance, np.float64)
        t[gi] = np.asarray(te, np.float64)
        fb[gi] = np.asarray(r.fallback)
    return PerfectTrace(L, t, fb)
