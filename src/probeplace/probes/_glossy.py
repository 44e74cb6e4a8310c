"""Glossy reads from light-field probes: radiance along rays, filtered by direction and footprint.

* :func:`glossy_trace` / :func:`glossy_radiance` — trace rays through the probes (``trace_light_field``)
  and read the radiance at the hit (McGuire et al. 2017 §5.1: "glossy reflection … trace a ray through the
  light field and read the radiance"). The read is by **direction**: the radiance map of the probe p that
  resolved the hit is sampled in the direction from p to the hit point x = o + t·d, so the radiance map's
  resolution is independent of the tracer's geometry maps. Three filters (``GLOSSY_FILTERS``):

  - ``"texel"``: the one texel containing that direction, unfiltered (the nearest texel; it is the texel
    the tracer resolved when the maps share a resolution) — kept for comparison;
  - ``"bilinear"``: bilinear on the bordered level-0 map (``_core.sample_bilinear``);
  - ``"mip"``: trilinear on a radiance MIP chain (:func:`radiance_mips`), the level chosen from the ray's
    footprint. A ray carries a cone of solid angle Ω_s at its origin (for a BRDF sample the filtered
    importance sampling footprint Ω_s = 1 / (N · pdf(ωᵢ)), N samples per pixel: Colbert & Křivánek 2007,
    "GPU-Based Importance Sampling", GPU Gems 3 ch. 20, Eq. 13; rougher lobes → lower pdf → wider cone).
    At the hit the cone covers ≈ Ω_s t² of surface, which the probe sees under Ω_p = Ω_s (t / r)², r the
    probe–hit distance (McGuire §5.1's "texel solid angle vs pixel solid angle at the probe" criterion,
    turned around). The level is ½ log₂(Ω_p / Ω_texel) + ``lod_bias`` with Ω_texel = 4π / R² the mean
    level-0 texel solid angle, clamped to the chain and blended linearly between the two nearest levels
    (the split-sum "pre-filtered radiance, level from roughness" of Karis 2013, Luo 2022 §4.1.3 / Eq. 4.4).
    Without a cone (``cone=None``) it is level 0, i.e. ``"bilinear"``.

  - ``"depth_aware"``: bilinear over the texels whose *surfel* lies at the hit — each of the four texels'
    surfel plane (the geometry map's distance and normal at the texel centre, McGuire §4.1) is met along
    the read direction at r_i; a texel counts when |r_i − r| ≤ ``DEPTH_TOLERANCE`` · r, r the probe–hit
    distance, and the weights of those that count are renormalised (all four fail: plain bilinear). A
    plain bilinear read at a silhouette blends the near surface's texels with those of the surface
    behind it (a shadowed pillar edge with the sun-lit floor beyond); the depth test keeps the blend on
    the surface that was hit — the visibility weighting of McGuire §5 and DDGI's probe weights, applied
    to the four texels of one probe.
  - ``"depth_normal"`` (the default): ``"depth_aware"`` whose texels must also face as the hit's surface
    does — a texel counts when its surfel lies at the hit and its normal n_i meets the hit's n_h with
    n_i · n_h ≥ ``NORMAL_COS`` (n_i turned toward the probe; n_h the surfel of the geometry texel the
    trace resolved, in the probe it reads — or, for the perfect trace, the exact hit's normal facing the
    ray's origin, the side of the probe that sees the hit); when none does, the depth test alone decides,
    as in ``"depth_aware"``. Why: a plane seen at a grazing angle passes within the depth tolerance of
    points that are not on it. On Crytek Sponza a sunlit floor seen at 83° from a probe 10 m away,
    extended along the read direction, passes within 3–8 % of the distance of small shaded faces standing
    on it, so their reads blended the floor's sun in (experiments/README.md §2, "What the tail is made
    of"); the face the worst of those rays hit turns 79° from the floor. On the ``sponza_comparison``
    preset (seed 0, 128 probes) the normal test lowered every method's glossy MSE by 29–45 % (the grid
    0.50 → 0.28× a black image) and the trace's excess over the perfect trace to 0.08–1.31 (0.65–1.93
    before).

  Misses read zero (reflected radiance) or the sky (``include_emission``). Unresolved rays fall back to the
  radiance the usable probe nearest to the last free point sees in the ray's direction (a distant-light
  approximation, the classic "nearest reflection probe"), read with the same filter, and are reported.
* :func:`perfect_trace_radiance` — the representation floor of the evaluation (docs/evaluate.md): given
  the *exact* hit of each ray (Embree), read the radiance at that point from the probes, by direction
  from the nearest usable probe that sees it, with the same filter. A probe sees x when it lies on the
  side of x's surface the ray came from and its surfel in the direction of x (the nearest distance texel's
  plane, McGuire §4.1) is not nearer than |x − p| · (1 − ``margin``); among the ``candidates`` nearest
  usable probes the nearest such probe is used (``choose="sharpest"``: the smallest texel footprint on
  the surface, r²/cos θ; ``"aligned"``: the view most like the ray's), else the nearest usable probe (a
  *fallback*, counted).

Radiance MIPs average 2×2 texels weighted by their exact solid angles (so ∫ L dω is the same at every
level) and redo the octahedral border at each level (``_core.add_border``), so bilinear reads stay
continuous across the fold at every level.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from .._core import (
    ConfigError,
    LightFieldProbes,
    add_border,
    next_pow2,
    oct_encode,
    safe_normalize,
    strip_border,
    surfel_directions,
    surfel_texels,
    texel_directions,
    texel_of_direction,
    texel_solid_angles,
)
from .tracer import LightFieldTracer, TraceStatus, trace_light_field

GLOSSY_FILTERS = ("texel", "bilinear", "mip", "depth_aware", "depth_normal")
#: The filters that read the radiance texels' surfels (``glossy_maps``: level 0 and its surfel maps).
_SURFEL_FILTERS = ("depth_aware", "depth_normal")
#: The filter of every glossy read unless one is chosen (the evaluation's too, ``EvalConfig.glossy_filter``):
#: module docstring (``"depth_aware"`` had lowered Sponza 16×8×8's glossy MSE at 64² from 1.95 to 1.81× a
#: black image against plain bilinear; the normal test took the preset's 29–45 % lower again).
DEFAULT_GLOSSY_FILTER = "depth_normal"
#: ``"depth_aware"``: a texel counts when its surfel meets the read direction within this fraction of the
#: probe–hit distance (module docstring).
DEPTH_TOLERANCE = 0.1
#: ``"depth_normal"``: a texel counts only when its surfel's normal is within acos(0.8) ≈ 37° of the hit's
#: (module docstring). Normals of one surface in the 512² maps differ by the bfloat16 rounding and the
#: surface's curvature across a radiance texel; the face that leaked the most turns 79° from the floor.
NORMAL_COS = 0.8
PERFECT_TRACE_CHOICES = ("nearest", "sharpest", "aligned")
_CHUNK = 1 << 14


class GlossyResult(eqx.Module):
    """Per ray: radiance read, tracer status (TraceStatus MISS / HIT / UNRESOLVED), distance t (inf on a
    miss; the last free point if unresolved), probe read (-1 on a miss) and the MIP level used."""

    radiance: Float[Array, "n 3"]
    status: Int[Array, " n"]
    t: Float[Array, " n"]
    probe: Int[Array, " n"]
    lod: Float[Array, " n"]


class PerfectTraceResult(eqx.Module):
    """Per ray: radiance read at the exact hit, probe read (-1 on an exact miss), whether no candidate
    probe saw the hit (the nearest usable probe was read instead) and the MIP level used."""

    radiance: Float[Array, "n 3"]
    probe: Int[Array, " n"]
    fallback: Bool[Array, " n"]
    lod: Float[Array, " n"]


# ------------------------------------------------------------------------------------------ maps
def radiance_mips(lf: LightFieldProbes, *, include_emission: bool = False) -> tuple[Array, ...]:
    """Radiance MIP chain (module docstring): bordered maps of interior resolution R, R/2, …, 1.

    Args:
        lf: baked probes (power-of-two radiance maps).
        include_emission: filter radiance + emission (what a ray sees) instead of reflected radiance.

    Returns:
        Tuple of (n_probes, R/2ᵏ + 2, R/2ᵏ + 2, 3) bordered maps, level 0 first (level 0 is the stored
        map's interior with its border redone, equal to the stored map).
    """
    rad = strip_border(lf.radiance)
    if include_emission:
        rad = rad + strip_border(lf.emission)
    res = rad.shape[-2]
    if res < 1 or res & (res - 1):
        raise ConfigError(f"radiance MIPs need power-of-two maps, got resolution {res}")
    w = texel_solid_angles(res, rad.dtype)
    levels = [add_border(rad)]
    while rad.shape[-2] > 1:
        p, r = rad.shape[0], rad.shape[-2]
        lw = (rad * w[None, :, :, None]).reshape(p, r // 2, 2, r // 2, 2, 3).sum(axis=(2, 4))
        w = w.reshape(r // 2, 2, r // 2, 2).sum(axis=(1, 3))
        rad = lw / w[None, :, :, None]
        levels.append(add_border(rad))
    return tuple(levels)


def _bilinear(maps: Float[Array, "p rb rb c"], p: Int[Array, ""], direction: Float[Array, "3"]) -> Array:
    """``_core.sample_bilinear(maps[p], direction)`` without gathering the whole map of probe p."""
    res = maps.shape[-2] - 2
    s = jnp.clip((oct_encode(direction) + 1.0) * (res / 2.0) + 0.5, 0.5, res + 0.5)
    i0 = jnp.minimum(jnp.floor(s).astype(jnp.int32), res)
    f = s - i0.astype(s.dtype)
    c0, r0, fu, fv = i0[0], i0[1], f[0], f[1]
    a, b = maps[p, r0, c0], maps[p, r0, c0 + 1]
    c, d = maps[p, r0 + 1, c0], maps[p, r0 + 1, c0 + 1]
    return (a * (1 - fu) + b * fu) * (1 - fv) + (c * (1 - fu) + d * fu) * fv


def _nearest(maps: Array, p: Int[Array, ""], direction: Float[Array, "3"]) -> Array:
    rc = texel_of_direction(maps.shape[-2] - 2, direction)
    return maps[p, rc[0] + 1, rc[1] + 1]


@eqx.filter_jit  # one program, not one per operation (issue 32); ``res`` is static
def _surfel_maps(lf: LightFieldProbes, res: int) -> tuple[Array, Array]:
    """Bordered (p, res+2, res+2, 3) maps of each radiance texel's surfel: the point d·ω relative to the
    probe and the normal, from the geometry texel (of the bake's bordered distance and normal maps)
    holding the radiance texel's centre (``_core.surfel_texels``; the geometry maps may be finer) — the
    texel whose direction ω the bake traces the radiance along (``BakeConfig.texel_rays="surfel"``). Only
    those texels are unpacked (``LightFieldProbes.normal_at``), not the whole normal maps."""
    idx = surfel_texels(res, lf.geometry_res)
    rows, cols = (a.reshape(-1) for a in np.meshgrid(idx, idx, indexing="ij"))
    omega = surfel_directions(res, lf.geometry_res, lf.far.dtype).reshape(-1, 3)
    at = (slice(None), rows + 1, cols + 1)
    point = (lf.distance[at][..., None] * omega[None]).reshape(-1, res, res, 3)
    normal = lf.normal_at(*at).reshape(-1, res, res, 3)
    return add_border(point), add_border(normal)


def _bilinear_depth(maps, points, normals, p, direction, r, n_hit=None) -> Array:
    """Bilinear read of probe p in ``direction`` over the texels whose surfel lies at distance r
    (module docstring, ``"depth_aware"``) and, given the hit's normal ``n_hit``, faces as it does
    (``"depth_normal"``; none does: the depth test alone)."""
    res = maps.shape[-2] - 2
    s = jnp.clip((oct_encode(direction) + 1.0) * (res / 2.0) + 0.5, 0.5, res + 0.5)
    i0 = jnp.minimum(jnp.floor(s).astype(jnp.int32), res)
    f = s - i0.astype(s.dtype)
    rows = i0[1] + jnp.array([0, 0, 1, 1], i0.dtype)
    cols = i0[0] + jnp.array([0, 1, 0, 1], i0.dtype)
    w = jnp.stack([(1 - f[0]) * (1 - f[1]), f[0] * (1 - f[1]), (1 - f[0]) * f[1], f[0] * f[1]])
    x, n = points[p, rows, cols], normals[p, rows, cols]
    wn = n @ direction
    ok = jnp.abs(wn) > 1e-3
    r_i = jnp.where(ok, jnp.sum(x * n, axis=-1) / jnp.where(ok, wn, 1.0), jnp.inf)
    at_hit = ok & (jnp.abs(r_i - r) <= DEPTH_TOLERANCE * r)
    if n_hit is not None:
        facing = at_hit & (n @ n_hit >= NORMAL_COS)
        at_hit = jnp.where(jnp.any(facing), facing, at_hit)
    wd = jnp.where(at_hit, w, 0.0)
    total = jnp.sum(wd)
    w = jnp.where(total > 0, wd / jnp.where(total > 0, total, 1.0), w)
    return w @ maps[p, rows, cols]


def _read(levels, filt: str, p, direction, lod, r=None, n_hit=None):
    """Filtered read of probe ``p``'s radiance in ``direction`` at MIP level ``lod`` (single ray); ``r``:
    the probe–hit distance (``"depth_aware"``, ``"depth_normal"``; inf: no hit to match, a plain bilinear
    read); ``n_hit``: the hit's normal, facing the probe (``"depth_normal"``)."""
    if filt == "texel":
        return _nearest(levels[0], p, direction)
    if filt in _SURFEL_FILTERS:
        n_hit = n_hit if filt == "depth_normal" else None
        return _bilinear_depth(levels[0], levels[1], levels[2], p, direction, r, n_hit)
    if filt == "bilinear" or len(levels) == 1:
        return _bilinear(levels[0], p, direction)
    lod = jnp.clip(lod, 0.0, len(levels) - 1.0)
    out = jnp.zeros(3, levels[0].dtype)
    for k, m in enumerate(levels):  # trilinear: only the two levels around lod get a weight
        wk = jnp.maximum(1.0 - jnp.abs(lod - k), 0.0)
        out = out + wk * _bilinear(m, p, direction)
    return out


def _lod(cone, t, r, res: int, bias):
    """½ log₂(Ω_s (t/r)² / (4π/R²)) + bias (module docstring); −inf-safe, ≥ 0."""
    tiny = jnp.finfo(cone.dtype).tiny
    omega_p = cone * (t / jnp.maximum(r, 1e-12)) ** 2
    ratio = omega_p / (4.0 * math.pi / (res * res))
    lod = 0.5 * jnp.log2(jnp.maximum(ratio, tiny)) + bias
    return jnp.where((cone > 0) & jnp.isfinite(lod), jnp.maximum(lod, 0.0), 0.0)


# ------------------------------------------------------------------------------------------ kernels
def _dist2(
    x: Float[Array, "n 3"], pos: Float[Array, "p 3"], usable: Bool[Array, " p"]
) -> Float[Array, "n p"]:
    """Squared distances, inf for unusable probes; |x|² − 2x·p + |p|² (a matmul: no (n, p, 3) temporary;
    only used to rank probes, where its rounding is harmless)."""
    d2 = jnp.sum(x * x, axis=1)[:, None] - 2.0 * (x @ pos.T) + jnp.sum(pos * pos, axis=1)[None, :]
    return jnp.where(usable[None, :], jnp.maximum(d2, 0.0), jnp.inf)


@eqx.filter_jit
def _glossy_chunk(tr: LightFieldTracer, levels, o, d, cone, sky, bias, filt: str, include_emission: bool):
    res = trace_light_field(tr, o, d)
    hit = res.status == TraceStatus.HIT
    t_free = jnp.where(jnp.isfinite(res.t), res.t, 0.0)
    x = o + t_free[:, None] * d
    # Unresolved: the usable probe nearest to the last free point, read along d (distant light).
    near = jnp.argmin(_dist2(x, tr.pos_world, tr.usable), axis=1).astype(jnp.int32)
    p = jnp.where(hit, jnp.maximum(res.probe, 0), near)
    v = x - tr.pos_world[p]
    r = jnp.linalg.norm(v, axis=-1)
    direction = jnp.where(hit[:, None], safe_normalize(v), d)
    r0 = levels[0].shape[-2] - 2
    # A hit is seen from the probe (distance ratio t/r); the fallback is at infinity (ratio 1).
    lod = jnp.where(
        hit, _lod(cone, t_free, r, r0, bias), _lod(cone, jnp.ones_like(r), jnp.ones_like(r), r0, bias)
    )
    r_hit = jnp.where(hit, r, jnp.inf)  # an unresolved ray's fallback read has no hit to match
    # the hit's normal: the surfel of the geometry texel the trace resolved, in the probe it read
    n_hit = tr.surfels(tr.row[p], res.texel[:, 0] + 1, res.texel[:, 1] + 1)[1]
    val = jax.vmap(lambda pi, di, li, ri, ni: _read(levels, filt, pi, di, li, ri, ni))(
        p, direction, lod, r_hit, n_hit
    )
    miss = jnp.broadcast_to(sky[None, :], val.shape) if include_emission else jnp.zeros_like(val)
    out = jnp.where((res.status == TraceStatus.MISS)[:, None], miss, val)
    probe = jnp.where(res.status == TraceStatus.MISS, -1, p)
    return GlossyResult(out, res.status, res.t, probe, jnp.where(res.status == TraceStatus.MISS, 0.0, lod))


def _sees(lf: LightFieldProbes, p, x, n_front, margin):
    """Whether probe ``p`` sees the point x on a surface facing ``n_front`` (module docstring)."""
    v = x - lf.pos_world[p]
    r = jnp.linalg.norm(v)
    w = safe_normalize(v)
    same_side = jnp.dot(-v, n_front) > 0
    dres = lf.geometry_res
    rc = texel_of_direction(dres, w)
    dist_c = lf.distance[p, rc[0] + 1, rc[1] + 1]
    # The texel's surfel (McGuire §4.1): the plane through dist_c·ω_c with the baked normal, met along w.
    omega_c = texel_directions(dres, x.dtype)[rc[0], rc[1]]
    ns = lf.normal_at(p, rc[0] + 1, rc[1] + 1)
    xs_n = dist_c * jnp.dot(omega_c, ns)
    w_n = jnp.dot(w, ns)
    ok = (jnp.abs(w_n) > 1e-3) & (xs_n * w_n > 0)
    r_surf = jnp.where(ok, xs_n / jnp.where(ok, w_n, 1.0), dist_c)
    return same_side & (r_surf >= r * (1.0 - margin))


@eqx.filter_jit
def _perfect_chunk(
    lf, levels, o, d, t, n, cone, sky, bias, margin, k: int, filt: str, include_emission: bool, choose: str
):
    usable = lf.active & ~lf.inside
    hit = jnp.isfinite(t)
    x = o + jnp.where(hit, t, 0.0)[:, None] * d
    n_front = n * jnp.where(jnp.sum(n * d, axis=-1) > 0, -1.0, 1.0)[:, None]
    # The k nearest usable probes, nearest first.
    neg, cand = jax.lax.top_k(-_dist2(x, lf.pos_world, usable), k)
    ok = jnp.isfinite(neg) & jax.vmap(
        lambda c, xi, ni: jax.vmap(lambda pi: _sees(lf, pi, xi, ni, margin))(c)
    )(cand, x, n_front)
    if choose == "nearest":
        first = jnp.argmax(ok, axis=1)
    else:
        v = x[:, None, :] - lf.pos_world[cand]
        view = safe_normalize(v)
        if choose == "aligned":  # the seeing candidate whose view of x is most like the ray's
            score = jnp.sum(view * d[:, None, :], axis=-1)
        else:  # "sharpest": smallest texel footprint on the surface, ∝ r² / cos θ (θ: view to normal)
            cos = jnp.abs(jnp.sum(view * n_front[:, None, :], axis=-1))
            score = -jnp.sum(v * v, axis=-1) / jnp.maximum(cos, 1e-3)
        first = jnp.argmax(jnp.where(ok, score, -jnp.inf), axis=1)
    any_ok = jnp.any(ok, axis=1)
    p = jnp.where(any_ok, jnp.take_along_axis(cand, first[:, None], axis=1)[:, 0], cand[:, 0]).astype(
        jnp.int32
    )
    v = x - lf.pos_world[p]
    r = jnp.linalg.norm(v, axis=-1)
    lod = _lod(cone, jnp.where(hit, t, 0.0), r, levels[0].shape[-2] - 2, bias)
    # the exact hit's normal, facing the ray's origin: the side the probe that sees x is on
    val = jax.vmap(lambda pi, di, li, ri, ni: _read(levels, filt, pi, di, li, ri, ni))(
        p, safe_normalize(v), lod, r, n_front
    )
    miss = jnp.broadcast_to(sky[None, :], val.shape) if include_emission else jnp.zeros_like(val)
    out = jnp.where(hit[:, None], val, miss)
    return PerfectTraceResult(out, jnp.where(hit, p, -1), hit & ~any_ok, jnp.where(hit, lod, 0.0))


def _chunked(fn, arrays, chunk: int):
    """Run ``fn(*arrays)`` over fixed-size row chunks (the last padded by repeating its edge row) so
    every chunk reuses one compile; concatenate the (pytree) outputs."""
    n = arrays[0].shape[0]
    size = next_pow2(n, lo=64, hi=chunk)
    outs = []
    for s in range(0, n, size):
        k = min(size, n - s)
        pad = lambda a, s=s, k=k: jnp.pad(
            a[s : s + k], [(0, size - k)] + [(0, 0)] * (a.ndim - 1), mode="edge"
        )
        outs.append(jax.tree.map(lambda y, k=k: y[:k], fn(*(pad(a) for a in arrays))))
    return jax.tree.map(lambda *ys: jnp.concatenate(ys), *outs)


def glossy_maps(
    lf: LightFieldProbes, filter: str = DEFAULT_GLOSSY_FILTER, *, include_emission: bool = True
) -> tuple[Array, ...]:
    """The maps a glossy read with ``filter`` uses, built once for many calls (pass them as ``maps`` to
    :func:`glossy_trace` / :func:`perfect_trace_radiance`): the MIP chain for ``"mip"``
    (:func:`radiance_mips`), level 0 and its surfels for ``"depth_aware"`` and ``"depth_normal"``, else
    level 0 alone.
    ``include_emission`` as in :func:`glossy_trace` (radiance + emission, or reflected radiance only)."""
    if filter not in GLOSSY_FILTERS:
        raise ConfigError(f"glossy filter must be one of {GLOSSY_FILTERS}, got {filter!r}")
    if filter == "mip":
        return radiance_mips(lf, include_emission=include_emission)
    level0 = lf.radiance + lf.emission if include_emission else lf.radiance
    if filter in _SURFEL_FILTERS:
        return (level0, *_surfel_maps(lf, level0.shape[-2] - 2))
    return (level0,)


def _levels(lf: LightFieldProbes, filt: str, include_emission: bool, maps) -> tuple[Array, ...]:
    """``maps`` if given (level 0 alone of them for the texel and bilinear reads), else
    :func:`glossy_maps`."""
    if maps is None:
        return glossy_maps(lf, filt, include_emission=include_emission)
    return tuple(maps) if filt in ("mip", *_SURFEL_FILTERS) else (maps[0],)


def _check(filt: str, o, d, dt, cone):
    if filt not in GLOSSY_FILTERS:
        raise ConfigError(f"glossy filter must be one of {GLOSSY_FILTERS}, got {filt!r}")
    o = jnp.asarray(o, dt)
    d = jnp.asarray(d, dt)
    if o.ndim != 2 or o.shape[-1] != 3 or d.shape != o.shape:
        raise ValueError(f"origins and directions must both be (n, 3), got {o.shape} and {d.shape}")
    c = jnp.zeros(o.shape[:1], dt) if cone is None else jnp.broadcast_to(jnp.asarray(cone, dt), o.shape[:1])
    return o, d, c


# ------------------------------------------------------------------------------------------ public
def glossy_trace(
    tracer: LightFieldTracer,
    lf: LightFieldProbes,
    origins: Float[Array, "n 3"],
    directions: Float[Array, "n 3"],
    *,
    cone: Float[Array, " n"] | float | None = None,
    filter: str = DEFAULT_GLOSSY_FILTER,
    lod_bias: float = 0.0,
    include_emission: bool = True,
    sky: Float[Array, "3"] | None = None,
    maps: tuple[Array, ...] | None = None,
    chunk: int = _CHUNK,
) -> GlossyResult:
    """Radiance arriving at ``origins`` from ``directions``, read from the probes (module docstring).

    Args:
        tracer: :func:`~probeplace.probes.make_tracer` of ``lf``.
        lf: the baked probes whose maps are read.
        origins, directions: rays, world frame (offset secondary rays off their surface yourself).
        cone: per-ray footprint solid angle at the origin, sr (``"mip"`` only; ``None``: level 0).
        filter: one of :data:`GLOSSY_FILTERS` (module docstring; default :data:`DEFAULT_GLOSSY_FILTER`).
        lod_bias: added to the MIP level (``"mip"``; Colbert & Křivánek use +1 for smoother results).
        include_emission: add the emission baked at the hit, and the sky on a miss (what the ray would
            see); ``False`` gives reflected radiance only (the glossy *indirect* input).
        sky: radiance of escaping rays (default zero; pass ``scene.sky_radiance``). No sun disk.
        maps: :func:`glossy_maps` of ``lf`` with the same filter and ``include_emission`` (built when
            ``None``; pass them to build once for many calls).
        chunk: rays per jitted chunk.

    Returns:
        :class:`GlossyResult`; unresolved rays carry the fallback radiance and their status.
    """
    dt = tracer.pos_world.dtype
    o, d, c = _check(filter, origins, directions, dt, cone)
    if o.shape[0] == 0:
        z = jnp.zeros((0,), dt)
        return GlossyResult(
            jnp.zeros((0, 3), dt), jnp.zeros((0,), jnp.int32), z, jnp.zeros((0,), jnp.int32), z
        )
    levels = _levels(lf, filter, include_emission, maps)
    s = jnp.zeros(3, dt) if sky is None else jnp.asarray(sky, dt)
    b = jnp.asarray(lod_bias, dt)
    fn = lambda o_, d_, c_: _glossy_chunk(tracer, levels, o_, d_, c_, s, b, filter, include_emission)
    return _chunked(fn, (o, d, c), chunk)


def glossy_radiance(
    tracer: LightFieldTracer,
    lf: LightFieldProbes,
    origins: Float[Array, "n 3"],
    directions: Float[Array, "n 3"],
    **kw,
) -> tuple[Float[Array, "n 3"], Int[Array, " n"]]:
    """:func:`glossy_trace` → (radiance (n, 3), status (n,) TraceStatus MISS=0 / HIT=1 / UNRESOLVED=2)."""
    res = glossy_trace(tracer, lf, origins, directions, **kw)
    return res.radiance, res.status


def perfect_trace_radiance(
    lf: LightFieldProbes,
    origins: Float[Array, "n 3"],
    directions: Float[Array, "n 3"],
    t_hit: Float[Array, " n"],
    hit_normals: Float[Array, "n 3"],
    *,
    cone: Float[Array, " n"] | float | None = None,
    filter: str = DEFAULT_GLOSSY_FILTER,
    lod_bias: float = 0.0,
    include_emission: bool = False,
    sky: Float[Array, "3"] | None = None,
    margin: float = 0.05,
    candidates: int = 8,
    choose: str = "nearest",
    maps: tuple[Array, ...] | None = None,
    chunk: int = 1 << 12,
) -> PerfectTraceResult:
    """Radiance read from the probes at each ray's *exact* hit (module docstring): the representation
    floor of the glossy image, with the tracer taken out.

    Args:
        lf: baked probes.
        origins, directions: rays, world frame.
        t_hit: exact hit distance (``inf`` on a miss), e.g. ``caster.closest_hit(o, d).t``.
        hit_normals: geometric normal at the hit (either side; it is turned toward the ray's origin).
        cone, filter, lod_bias, include_emission, sky, maps: as in :func:`glossy_trace`.
        margin: a probe sees the hit if its surfel toward it is ≥ (1 − margin) × the probe–hit distance
            (5% by default: the surfel is a plane through one texel centre, not the exact surface).
        candidates: how many of the nearest usable probes are tested.
        choose: which seeing candidate is read: ``"nearest"`` (default), ``"sharpest"`` (the smallest
            texel footprint on the hit's surface, r² / cos θ) or ``"aligned"`` (the view of the hit most
            like the ray's, for view-dependent radiance).
        chunk: rays per jitted chunk (memory ∝ chunk × n_probes).

    Returns:
        :class:`PerfectTraceResult`.
    """
    if not bool(jnp.any(lf.active & ~lf.inside)):
        raise ConfigError(
            "the perfect trace needs at least one usable probe (active and not inside geometry)"
        )
    dt = lf.pos_world.dtype
    o, d, c = _check(filter, origins, directions, dt, cone)
    t = jnp.asarray(t_hit, dt)
    n = jnp.asarray(hit_normals, dt)
    if t.shape != o.shape[:1] or n.shape != o.shape:
        raise ValueError(
            f"t_hit must be (n,) and hit_normals (n, 3) for n = {o.shape[0]}, got {t.shape}, {n.shape}"
        )
    if o.shape[0] == 0:
        z = jnp.zeros((0,), dt)
        return PerfectTraceResult(jnp.zeros((0, 3), dt), jnp.zeros((0,), jnp.int32), jnp.zeros((0,), bool), z)
    levels = _levels(lf, filter, include_emission, maps)
    s = jnp.zeros(3, dt) if sky is None else jnp.asarray(sky, dt)
    k = int(min(max(candidates, 1), lf.pos_world.shape[0]))
    b, m = jnp.asarray(lod_bias, dt), jnp.asarray(margin, dt)
    if choose not in PERFECT_TRACE_CHOICES:
        raise ConfigError(f"choose must be one of {PERFECT_TRACE_CHOICES}, got {choose!r}")
    fn = lambda *a: _perfect_chunk(lf, levels, *a, s, b, m, k, filter, include_emission, choose)
    return _chunked(fn, (o, d, t, n, c), chunk)


__all__ = [
    "DEFAULT_GLOSSY_FILTER",
    "GLOSSY_FILTERS",
    "GlossyResult",
    "PerfectTraceResult",
    "glossy_maps",
    "glossy_radiance",
    "glossy_trace",
    "perfect_trace_radiance",
    "radiance_mips",
]
