"""One wavefront bounce of the reference path tracer: shading and sampling between two ray casts.

Each bounce k ≥ 1 is (1) one batched closest-hit query for all paths (done by the caller through a
ray caster), (2) :func:`shade` — emission at the hit with MIS, one light sample (NEE), one BRDF sample,
Russian roulette — (3) one batched shadow query for the light samples (caller), (4) :func:`add_shadowed`.
Shading is jitted JAX; the casts go through any :class:`~probeplace.geometry.AbstractRayCaster`.

Components (DESIGN.md "indirect means reflected"; documented in docs/render.md). Vertex x₁ is the
first surface the camera ray hits, x_k the k-th:

* ``emission``: radiance emitted by x₁ toward the camera, or the sky/sun seen directly by the camera;
* ``direct``: light that reaches x₁ straight from an emitter (area light, sun or sky) and is reflected
  there: NEE at x₁ plus, MIS-weighted, BRDF-sampled rays from x₁ that hit an emitter or escape;
* ``diffuse_indirect`` / ``glossy_indirect``: light reflected at x₁ that was itself *reflected* (not
  emitted) by another surface x₂ (paths with ≥ 2 scattering vertices), split by the lobe sampled at x₁
  (the one-sample lobe estimator f_k cos / (p_k pdf_k), so each part is unbiased for its own lobe);
* ``full`` = the sum of the four;
* ``glossy_direct``: the part of ``direct`` reflected by x₁'s *specular* lobe (NEE with f_s, and the
  BRDF-sampled emitter hits of paths that sampled the specular lobe at x₁) — a breakdown, not a fifth
  term of ``full``. ``direct − glossy_direct + diffuse_indirect`` is the radiance x₁ reflects by its
  diffuse lobe: view-independent, what a light probe stores for every viewer (``probes._bake``).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int, UInt32

from .._core import Hit, Materials
from ._brdf import BrdfParams, eval_brdf, pdf_brdf, sample_brdf
from ._lights import LightTable, area_light_pdf, sample_light, sun_hit
from ._sampling import (
    DIM_LIGHT_TYPE,
    DIM_LOBE,
    DIM_RR,
    dot3,
    make_frame,
    path_uniforms,
    power_heuristic,
    to_local,
    to_world,
)

COMPONENTS = ("emission", "direct", "diffuse_indirect", "glossy_indirect", "full", "glossy_direct")
# Spawned rays start this far off the surface, relative to the point's magnitude: Mitsuba 3's
# math::RayEpsilon = 1500 · 2⁻²⁴ (include/mitsuba/core/math.h), so both renderers see the same geometry
# to within float32 round-off. Shadow rays stop short of the light by the relative ShadowEpsilon = 10×.
RAY_EPS = 1500.0 * 2.0**-24
SHADOW_EPS = 10.0 * RAY_EPS


class ShadeContext(eqx.Module):
    """Everything shading needs that is fixed for a render: materials, lights, sky, settings."""

    materials: Materials
    lights: LightTable
    sky: Float[Array, "3"]
    specular: Float[Array, ""]
    max_depth: Int[Array, ""]
    rr_depth: Int[Array, ""]


class Paths(eqx.Module):
    """State of a batch of paths between bounces (n = batch size).

    Attributes:
        origin, direction: the ray to trace next.
        throughput: path weight so far (camera → current ray), RR included.
        alive: still tracing.
        prev_pdf: solid-angle pdf of the BRDF sample that made the current ray (inf for camera rays:
            no MIS against light sampling there).
        spec_first: the lobe chosen at x₁ was the specular one.
        emission, direct, indirect: accumulated contributions per component (indirect not yet split).
        glossy_direct: the part of ``direct`` reflected by x₁'s specular lobe.
        pending: NEE contribution waiting for its shadow ray; pending_glossy: its specular-lobe part at
            x₁ (zero at later vertices).
        pixel, sample: the lane's pixel and sample index (random-number stream ids).
    """

    origin: Float[Array, "n 3"]
    direction: Float[Array, "n 3"]
    throughput: Float[Array, "n 3"]
    alive: Bool[Array, " n"]
    prev_pdf: Float[Array, " n"]
    spec_first: Bool[Array, " n"]
    emission: Float[Array, "n 3"]
    direct: Float[Array, "n 3"]
    indirect: Float[Array, "n 3"]
    glossy_direct: Float[Array, "n 3"]
    pending: Float[Array, "n 3"]
    pending_glossy: Float[Array, "n 3"]
    pixel: Int[Array, " n"]
    sample: Int[Array, " n"]


class ShadowRays(eqx.Module):
    """Shadow rays of one bounce: occluded if anything is hit with t < t_max."""

    origin: Float[Array, "n 3"]
    direction: Float[Array, "n 3"]
    t_max: Float[Array, " n"]


def init_paths(
    origin: Float[Array, "n 3"],
    direction: Float[Array, "n 3"],
    pixel: Int[Array, " n"],
    sample: Int[Array, " n"],
    valid: Bool[Array, " n"],
) -> Paths:
    """Fresh paths for camera rays (``valid`` False: padding lanes that never contribute)."""
    n = origin.shape[0]
    z3 = jnp.zeros((n, 3), origin.dtype)
    return Paths(
        origin=origin,
        direction=direction,
        throughput=jnp.ones((n, 3), origin.dtype),
        alive=valid,
        prev_pdf=jnp.full((n,), jnp.inf, origin.dtype),
        spec_first=jnp.zeros((n,), bool),
        emission=z3,
        direct=z3,
        indirect=z3,
        glossy_direct=z3,
        pending=z3,
        pending_glossy=z3,
        pixel=pixel,
        sample=sample,
    )


def _spawn_offset(x: Float[Array, "3"]) -> Float[Array, ""]:
    return (1.0 + jnp.max(jnp.abs(x))) * RAY_EPS


def _shade_one(ctx: ShadeContext, seed, k, lane, hit):
    """Shade one path at vertex x_k (single lane; see :func:`shade`)."""
    (o, d, thr, alive, prev_pdf, spec_first, pixel, sample) = lane
    (t, tri, ng, ns, mat) = hit
    u = path_uniforms(seed, pixel, sample, k)
    is_hit = alive & (tri >= 0)
    x = o + jnp.where(is_hit, t, 0.0) * d
    wo = -d
    # ---- emission at x_k (front faces only), MIS against light sampling from x_{k-1}
    cos_l = dot3(ng, wo)
    le = jnp.where(is_hit & (cos_l > 0), ctx.materials.emission[jnp.maximum(mat, 0)], 0.0)
    w_le = power_heuristic(prev_pdf, area_light_pdf(ctx.lights, tri, t, cos_l))
    # ---- escaped rays see the sky and, MIS-weighted, the sun's disk
    missed = alive & (tri < 0)
    in_sun, pdf_sun = sun_hit(ctx.lights, d)
    env = ctx.sky + jnp.where(in_sun, power_heuristic(prev_pdf, pdf_sun), 0.0) * ctx.lights.sun_radiance
    got = thr * (le * w_le + jnp.where(missed, env, jnp.zeros_like(env)))

    # ---- continue from x_k? (Mitsuba semantics: max_depth counts path segments)
    cont = is_hit & (k < ctx.max_depth)
    flip = jnp.where(cos_l < 0, -1.0, 1.0)  # two-sided BRDF: shade the side the ray came from
    ng_f = ng * flip
    ns_f = ns * flip
    tb, bb = make_frame(ns_f)
    wo_l = to_local(wo, tb, bb, ns_f)
    p = BrdfParams(
        base_color=ctx.materials.base_color[jnp.maximum(mat, 0)],
        roughness=ctx.materials.roughness[jnp.maximum(mat, 0)],
        metallic=ctx.materials.metallic[jnp.maximum(mat, 0)],
        specular=ctx.specular,
    )
    x_off = x + _spawn_offset(x) * ng_f
    # ---- next-event estimation: one light sample, MIS with the BRDF's pdf
    ls = sample_light(ctx.lights, x, u[DIM_LIGHT_TYPE : DIM_LIGHT_TYPE + 4])
    wi_l = to_local(ls.wi, tb, bb, ns_f)
    f_d, f_s = eval_brdf(p, wo_l, wi_l)
    pdf_d, pdf_s, ps = pdf_brdf(p, wo_l, wi_l)
    pdf_b = (1.0 - ps) * pdf_d + ps * pdf_s
    ok_l = cont & (ls.pdf > 0) & (dot3(ls.wi, ng_f) > 0) & (dot3(wo, ng_f) > 0)
    w_l = power_heuristic(ls.pdf, pdf_b)
    light = jnp.where(
        ok_l, thr * jnp.maximum(wi_l[2], 0.0) * ls.radiance * (w_l / jnp.where(ok_l, ls.pdf, 1.0)), 0.0
    )
    nee = light * (f_d + f_s)
    nee_glossy = jnp.where(k == 1, light * f_s, 0.0)  # x₁'s specular-lobe share (``glossy_direct``)
    shadow = (x_off, ls.wi, jnp.where(ok_l, ls.dist * (1.0 - SHADOW_EPS), 0.0))
    # ---- BRDF sample → the next ray
    bs = sample_brdf(p, wo_l, u[DIM_LOBE : DIM_LOBE + 3])
    wi = to_world(bs.wi, tb, bb, ns_f)
    ok_b = cont & (dot3(wi, ng_f) > 0) & (dot3(wo, ng_f) > 0)
    # At x₁ use the per-lobe weight so the diffuse/glossy split is unbiased; later the mixture weight.
    weight = jnp.where(k == 1, bs.weight_lobe, bs.weight)
    thr_new = jnp.where(ok_b, thr * weight, 0.0)
    spec_first = jnp.where(k == 1, bs.specular, spec_first)
    # ---- Russian roulette (Mitsuba's rule: from depth rr_depth on, survive with q = min(max β, 0.95))
    q = jnp.minimum(jnp.max(thr_new), 0.95)
    use_rr = k >= ctx.rr_depth
    survive = jnp.where(use_rr, u[DIM_RR] < q, True)
    thr_new = jnp.where(use_rr & survive & (q > 0), thr_new / jnp.where(q > 0, q, 1.0), thr_new)
    alive_new = ok_b & survive & jnp.any(thr_new > 0)
    new_lane = (x_off, wi, thr_new, alive_new, bs.pdf, spec_first)
    return got, (nee, nee_glossy), new_lane, shadow


def _route(
    paths: Paths,
    value: Float[Array, "n 3"],
    k_component: Int[Array, "*n"],
    glossy_direct: Float[Array, "n 3"],
) -> Paths:
    """Add ``value`` to the component of vertex depth ``k_component`` (1: emission, 2: direct, ≥3:
    indirect) — the depth at which that radiance *leaves its emitter* along the path. ``k_component``
    is one depth for all paths or one per path. ``glossy_direct``: the part of a direct ``value`` that
    x₁'s specular lobe reflected (added to ``glossy_direct`` where the value is direct)."""
    k_component = jnp.reshape(k_component, (-1, 1)) if jnp.ndim(k_component) else k_component
    return eqx.tree_at(
        lambda q: (q.emission, q.direct, q.indirect, q.glossy_direct),
        paths,
        (
            paths.emission + jnp.where(k_component == 1, value, 0.0),
            paths.direct + jnp.where(k_component == 2, value, 0.0),
            paths.indirect + jnp.where(k_component >= 3, value, 0.0),
            paths.glossy_direct + jnp.where(k_component == 2, glossy_direct, 0.0),
        ),
    )


def shade(
    ctx: ShadeContext, seed: UInt32[Array, ""], k: Int[Array, "*n"], paths: Paths, hit: Hit
) -> tuple[Paths, ShadowRays]:
    """Process the hits of bounce k (x_k) for every path: add emission (MIS'd), draw the light sample
    and the next ray. Returns the updated paths (NEE kept in ``pending``) and the shadow rays."""
    lane = (
        paths.origin,
        paths.direction,
        paths.throughput,
        paths.alive,
        paths.prev_pdf,
        paths.spec_first,
        paths.pixel,
        paths.sample,
    )
    hits = (hit.t, hit.tri, hit.geo_normal, hit.shading_normal, hit.material)
    k_lane = jnp.broadcast_to(k, paths.alive.shape)  # one bounce index for all paths, or one per path
    got, (nee, nee_glossy), new, shadow = jax.vmap(_shade_one, in_axes=(None, None, 0, 0, 0))(
        ctx, seed, k_lane, lane, hits
    )
    # Emission found at x_k left its emitter at depth k; NEE at x_k lights x_k, i.e. depth k + 1. An
    # emitter found at x₂ was reached by x₁'s BRDF sample: its lobe (``spec_first``, still x₁'s here).
    paths = _route(paths, got, k, jnp.where(paths.spec_first[:, None], got, 0.0))
    paths = eqx.tree_at(
        lambda q: (
            q.origin,
            q.direction,
            q.throughput,
            q.alive,
            q.prev_pdf,
            q.spec_first,
            q.pending,
            q.pending_glossy,
        ),
        paths,
        (*new, nee, nee_glossy),
    )
    return paths, ShadowRays(*shadow)


def add_shadowed(paths: Paths, occluded: Bool[Array, " n"], k: Int[Array, "*n"]) -> Paths:
    """Add the pending NEE contributions of bounce k whose shadow rays were not blocked."""
    value = jnp.where(occluded[:, None], 0.0, paths.pending)
    return _route(paths, value, k + 1, jnp.where(occluded[:, None], 0.0, paths.pending_glossy))


def components(paths: Paths) -> Float[Array, "n 6 3"]:
    """Per-path contributions in :data:`COMPONENTS` order (the full value is their sum)."""
    spec = paths.spec_first[:, None]
    diff_ind = jnp.where(spec, 0.0, paths.indirect)
    gloss_ind = jnp.where(spec, paths.indirect, 0.0)
    full = paths.emission + paths.direct + paths.indirect
    return jnp.stack([paths.emission, paths.direct, diff_ind, gloss_ind, full, paths.glossy_direct], axis=1)
