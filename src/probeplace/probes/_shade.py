"""Shading with light-field probes (McGuire et al. 2017 §5) and the two baselines in the same interface.

* :func:`diffuse_irradiance` — irradiance E(x, n) at surface points from the probes' irradiance maps.
  Each probe's sample E_p(n) is weighted as in McGuire §5 and DDGI (Majercik et al. 2019, §5.2,
  "Dynamic Diffuse Global Illumination with Ray-Traced Irradiance Fields", JCGT 8(2)):

  - **trilinear** weight over the cage of eight grid probes around x (uniform grids, :class:`GridIndex`);
    for non-uniform sets (:class:`VoxelIndex`) our documented generalisation: the voxel's K candidate
    probes weighted by **inverse distance** 1/‖x − p‖ instead of the trilinear weight;
  - **back-face** term ((ω·n + 1)/2)² + 0.2, ω the unit direction from x to the probe (DDGI's "smooth
    backface" weight: probes behind the surface count less but never zero);
  - **Chebyshev visibility** (McGuire §5.2): with the probe's filtered distance moments μ = E[r],
    E[r²] in the direction probe → x and the receiver's distance r, the one-tailed Chebyshev bound
    P(r_probe ≥ r) ≤ σ²/(σ² + (r − μ)²) when r > μ (1 when r ≤ μ: the receiver is closer than the
    mean occluder). As in DDGI it is cubed, floored at 0.05 and weights below 0.2 are crushed
    (w ← w³/0.2²) so a probe behind a wall contributes almost nothing. The receiver is moved off the
    surface by ``normal_bias`` × the probe spacing along n before the test (DDGI's normal bias).

  The weights are normalised; where every weight is zero (no usable probe around x) the nearest usable
  probe's irradiance is used. ``visibility=False`` drops the back-face and Chebyshev terms: the classic
  irradiance probes of Luo 2022 (trilinear interpolation only), the light-leak baseline.
* :func:`sh_irradiance` — the SH L2 baseline (Yang 2023): each probe's radiance map projected onto the
  real SH L2 basis (``_core.maths._sh``), irradiance E(n) = Σ Â_l c_lm Y_lm(n) (Ramamoorthi & Hanrahan 2001
  Eq. 8–9), interpolated with the same trilinear (or inverse-distance) weights, no visibility.
* :func:`glossy_radiance` — radiance arriving along rays, traced through the probes and read by
  direction at the hit with a texel / bilinear / MIP filter: ``probes/_glossy.py`` (re-exported here).

Which light the maps hold: ``lf.radiance`` is *reflected* radiance (DESIGN.md "indirect means
reflected"), and the irradiance maps are built from it; so E here is the irradiance due to light
reflected by other surfaces, the input of the diffuse *indirect* component.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._core import (
    ConfigError,
    LightFieldProbes,
    next_pow2,
    safe_normalize,
    sample_bilinear,
    strip_border,
    texel_directions,
    texel_solid_angles,
)
from .._core.maths import COSINE_LOBE, sh_basis
from ._glossy import glossy_radiance
from .tracer import GridIndex, VoxelIndex, grid_index, voxel_index

SHADINGS = ("lightfield", "irradiance", "sh")
_CHUNK = 1 << 14


# ------------------------------------------------------------------------------------------ helpers
def default_index(lf: LightFieldProbes, bounds: Float[Array, "2 3"] | None = None) -> GridIndex | VoxelIndex:
    """:func:`grid_index` when the probes form a full uniform grid, else :func:`voxel_index` over
    ``bounds`` (default: the probes' bounding box grown by 25% of its extent on every side)."""
    try:
        return grid_index(lf)
    except ConfigError:
        pass
    if bounds is None:
        pos = np.asarray(lf.pos_world, np.float64)
        lo, hi = pos.min(0), pos.max(0)
        pad = 0.25 * max(float((hi - lo).max()), 1e-6)
        bounds = np.stack([lo - pad, hi + pad])
    return voxel_index(lf, bounds)


def probe_spacing(lf: LightFieldProbes, index: GridIndex | VoxelIndex) -> float:
    """A length scale for the normal bias: the smallest grid spacing of a grid (axes with one node
    ignored); for other sets the median distance from each usable probe to its nearest neighbour."""
    if isinstance(index, GridIndex):
        sp = [float(s) for s, d in zip(np.asarray(index.spacing), index.dims, strict=True) if d > 1]
        return min(sp) if sp else 1.0
    pos = np.asarray(lf.pos_world, np.float64)[np.asarray(lf.active) & ~np.asarray(lf.inside)]
    if len(pos) < 2:
        return 1.0
    d = np.linalg.norm(pos[:, None] - pos[None], axis=-1)
    np.fill_diagonal(d, np.inf)
    return float(np.median(d.min(axis=1)))


def _candidates(index: GridIndex | VoxelIndex, pos: Array, x: Float[Array, "3"]):
    """(probe ids (k,), base weights (k,)): the trilinear cage, or the voxel's candidates weighted by
    inverse distance (module docstring). Ids are -1 where there is no usable probe."""
    if isinstance(index, GridIndex):
        ids, _ = index.cage(x)
        dims = jnp.asarray(index.dims, jnp.int32)
        f = (x - index.origin) / index.spacing
        base = jnp.clip(jnp.floor(f).astype(jnp.int32), 0, jnp.maximum(dims - 2, 0))
        a = jnp.clip(f - base.astype(x.dtype), 0.0, 1.0)
        i = jnp.arange(8, dtype=jnp.int32)
        off = jnp.stack([i % 2, (i // 2) % 2, (i // 4) % 2], axis=-1).astype(x.dtype)
        w = jnp.prod(jnp.where(off > 0.5, a[None, :], 1.0 - a[None, :]), axis=-1)
        return ids, w
    ids, _ = index.lookup(x)
    d = jnp.linalg.norm(pos[jnp.maximum(ids, 0)] - x[None, :], axis=-1)
    return ids, 1.0 / jnp.maximum(d, 1e-6)


def _chebyshev(moments: Float[Array, "mb mb 2"], v: Float[Array, "3"]) -> Float[Array, ""]:
    """DDGI's visibility weight for a receiver at ``v`` relative to the probe (McGuire §5.2 Chebyshev
    bound, cubed, floored at 0.05)."""
    r = jnp.linalg.norm(v)
    m = sample_bilinear(moments, safe_normalize(v))
    mean, mean2 = m[0], m[1]
    var = jnp.abs(mean2 - mean * mean)
    dr = jnp.maximum(r - mean, 0.0)
    cheb = var / jnp.maximum(var + dr * dr, jnp.finfo(v.dtype).tiny)
    return jnp.where(r > mean, jnp.maximum(cheb**3, 0.05), 1.0)


def _weights_one(lf_pos, usable, moments, index, x, n, bias, visibility: bool):
    """(candidate probes (k,), their unnormalised weights (k,), 0 where unusable; the nearest usable probe)
    at one point: the weights :func:`_blend_one` blends with (single instance; vmapped)."""
    ids, w = _candidates(index, lf_pos, x)
    ok = (ids >= 0) & usable[jnp.maximum(ids, 0)]
    p = jnp.maximum(ids, 0)
    if visibility:
        to_probe = safe_normalize(lf_pos[p] - x[None, :])
        back = ((to_probe @ n + 1.0) * 0.5) ** 2 + 0.2
        xb = x + bias * n
        vis = jax.vmap(_chebyshev)(moments[p], xb[None, :] - lf_pos[p])
        w_vis = back * vis
        # DDGI: crush tiny weights so a probe behind a wall fades out completely.
        w_vis = jnp.where(w_vis < 0.2, w_vis * w_vis * w_vis / 0.04, w_vis)
        w = w * w_vis
    w = jnp.where(ok, w, 0.0)
    # No usable probe around x: the nearest usable probe (any set).
    d2 = jnp.where(usable, jnp.sum((lf_pos - x[None, :]) ** 2, axis=-1), jnp.inf)
    near = jnp.argmin(d2).astype(jnp.int32)
    return p, w, near


def _blend_one(lf_pos, usable, values, moments, index, x, n, bias, visibility: bool):
    """Weighted blend of per-probe values (k, c) at one point (single instance; vmapped)."""
    p, w, near = _weights_one(lf_pos, usable, moments, index, x, n, bias, visibility)
    vals = values(p, n)  # (k, c)
    tot = jnp.sum(w)
    blended = jnp.sum(w[:, None] * vals, axis=0) / jnp.where(tot > 0, tot, 1.0)
    fallback = values(near[None], n)[0]
    return jnp.where(tot > 0, blended, fallback)


@eqx.filter_jit
def _weights_chunk(lf: LightFieldProbes, index, x, n, bias, visibility: bool):
    usable = lf.active & ~lf.inside

    def one(xi, ni):
        p, w, near = _weights_one(lf.pos_world, usable, lf.moments, index, xi, ni, bias, visibility)
        tot = jnp.sum(w)
        # normalised as the blend divides; where every weight is 0 the nearest usable probe alone
        w = jnp.where(tot > 0, w / jnp.where(tot > 0, tot, 1.0), 0.0)
        ids = jnp.concatenate([jnp.where(w > 0, p, -1), jnp.where(tot > 0, -1, near)[None]])
        w = jnp.concatenate([w, jnp.where(tot > 0, 0.0, 1.0)[None].astype(w.dtype)])
        return ids, w

    return jax.vmap(one)(x, n)


@eqx.filter_jit
def _irradiance_chunk(lf: LightFieldProbes, index, x, n, bias, visibility: bool):
    usable = lf.active & ~lf.inside

    def values(p, nrm):
        return jax.vmap(sample_bilinear, in_axes=(0, None))(lf.irradiance[p], nrm)

    fn = lambda xi, ni: _blend_one(lf.pos_world, usable, values, lf.moments, index, xi, ni, bias, visibility)
    return jax.vmap(fn)(x, n)


@eqx.filter_jit
def _sh_chunk(lf: LightFieldProbes, coeffs, index, x, n):
    usable = lf.active & ~lf.inside
    lobe = jnp.asarray(COSINE_LOBE, x.dtype)

    def values(p, nrm):
        y = sh_basis(nrm, xp=jnp) * lobe  # (9,)
        return jnp.einsum("k,pkc->pc", y, coeffs[p])

    fn = lambda xi, ni: _blend_one(lf.pos_world, usable, values, lf.moments, index, xi, ni, 0.0, False)
    return jax.vmap(fn)(x, n)


def _chunked(fn, points, normals, chunk: int, empty=None):
    """Run ``fn(x, n)`` over fixed-size chunks (the last one padded) so every chunk reuses one compile;
    ``fn`` returns an array or a tuple of arrays (per point), concatenated alike. ``empty``: the result for
    no points (default a (0, 3) array)."""
    pts = jnp.asarray(points)
    nrm = jnp.asarray(normals)
    if pts.ndim != 2 or pts.shape[-1] != 3 or nrm.shape != pts.shape:
        raise ValueError(f"points and normals must both be (n, 3), got {pts.shape} and {nrm.shape}")
    n = pts.shape[0]
    if n == 0:
        return jnp.zeros((0, 3), pts.dtype) if empty is None else empty
    size = next_pow2(n, lo=64, hi=chunk)
    outs = []
    for s in range(0, n, size):
        k = min(size, n - s)
        pad = lambda a, s=s, k=k: jnp.pad(a[s : s + k], ((0, size - k), (0, 0)), mode="edge")
        outs.append(jax.tree.map(lambda a, k=k: a[:k], fn(pad(pts), pad(nrm))))
    return jax.tree.map(lambda *parts: jnp.concatenate(parts), *outs)


def _prepare(lf: LightFieldProbes, points, index, bounds):
    if not bool(jnp.any(lf.active & ~lf.inside)):
        raise ConfigError("probe shading needs at least one usable probe (active and not inside geometry)")
    if index is None:
        index = default_index(lf, bounds)
    dt = lf.pos_world.dtype
    return index, dt


# ------------------------------------------------------------------------------------------ public
def diffuse_irradiance(
    lf: LightFieldProbes,
    points: Float[Array, "n 3"],
    normals: Float[Array, "n 3"],
    *,
    visibility: bool = True,
    index: GridIndex | VoxelIndex | None = None,
    bounds: Float[Array, "2 3"] | None = None,
    normal_bias: float = 0.2,
    chunk: int = _CHUNK,
) -> Float[Array, "n 3"]:
    """Irradiance E(x, n) (W m⁻² for radiance in W m⁻² sr⁻¹) at surface points from the irradiance maps.

    Args:
        lf: baked probes.
        points: receiver positions, world frame.
        normals: unit receiver normals (the side the light arrives on).
        visibility: McGuire's back-face and Chebyshev weights (True) or plain trilinear /
            inverse-distance interpolation, the classic irradiance probes (False).
        index: probe-selection index (default :func:`default_index`).
        bounds: scene bounds for a default voxel index of a non-uniform set.
        normal_bias: receiver offset along n for the visibility test, × the probe spacing.
        chunk: points per jitted chunk.

    Returns:
        (n, 3) irradiance, the dtype of ``lf``. Multiply by albedo/π for diffusely reflected radiance.
    """
    index, dt = _prepare(lf, points, index, bounds)
    bias = jnp.asarray(normal_bias * probe_spacing(lf, index), dt)
    fn = lambda x, n: _irradiance_chunk(lf, index, x.astype(dt), n.astype(dt), bias, visibility)
    return _chunked(fn, points, normals, chunk)


def sh_coefficients(lf: LightFieldProbes, *, include_emission: bool = False) -> Float[Array, "n_probes 9 3"]:
    """SH L2 coefficients of each probe's incident radiance (R&H 2001, three.js order, ``_core.maths._sh``).

    c_lm = Σ_texels L(ω) Y_lm(ω) Δω over the interior radiance map (exact texel solid angles).
    ``include_emission`` adds what the probe sees emitted (lights, sky): the probe's total incident
    radiance, as a Yang-2023-style SH probe would store it. The evaluation's diffuse *indirect* uses
    ``False`` (reflected light only, like the irradiance maps).
    """
    rad = strip_border(lf.radiance)
    if include_emission:
        rad = rad + strip_border(lf.emission)
    res = rad.shape[-2]
    dt = rad.dtype
    y = sh_basis(texel_directions(res, dt), xp=jnp) * texel_solid_angles(res, dt)[..., None]  # (r, r, 9)
    return jnp.einsum("ijk,pijc->pkc", y, rad)


def sh_irradiance(
    lf: LightFieldProbes,
    points: Float[Array, "n 3"],
    normals: Float[Array, "n 3"],
    *,
    coeffs: Float[Array, "n_probes 9 3"] | None = None,
    index: GridIndex | VoxelIndex | None = None,
    bounds: Float[Array, "2 3"] | None = None,
    chunk: int = _CHUNK,
) -> Float[Array, "n 3"]:
    """SH L2 irradiance baseline (Yang 2023): E(n) = Σ Â_l c_lm Y_lm(n) per probe, blended with the
    trilinear (or inverse-distance) weights and no visibility. ``coeffs`` default:
    :func:`sh_coefficients` (reflected radiance only)."""
    index, dt = _prepare(lf, points, index, bounds)
    c = sh_coefficients(lf) if coeffs is None else jnp.asarray(coeffs, dt)
    fn = lambda x, n: _sh_chunk(lf, c, index, x.astype(dt), n.astype(dt))
    return _chunked(fn, points, normals, chunk)


def irradiance_weights(
    lf: LightFieldProbes,
    points: Float[Array, "n 3"],
    normals: Float[Array, "n 3"],
    *,
    method: str = "lightfield",
    index: GridIndex | VoxelIndex | None = None,
    bounds: Float[Array, "2 3"] | None = None,
    normal_bias: float = 0.2,
    chunk: int = _CHUNK,
) -> tuple[np.ndarray, np.ndarray]:
    """Which probes :func:`shade_irradiance` blends at each point, and by how much: the same candidates
    and weights (``method``'s: McGuire's with visibility for ``"lightfield"``, trilinear / inverse
    distance without it for ``"irradiance"`` and ``"sh"``), normalised; where every weight is 0 the
    nearest usable probe with weight 1 (the shading's fallback). Not differentiable (host arrays).

    Args:
        lf, points, normals, index, bounds, normal_bias, chunk: as :func:`diffuse_irradiance`
            (``normal_bias`` is unused by ``"irradiance"`` and ``"sh"``, which have no visibility term).
        method: the shading method (:data:`SHADINGS`).

    Returns:
        (ids, weights): (n, k + 1) int32 probe indices (-1: no probe in that slot) and (n, k + 1) float
        weights summing to 1 per point, k the index's candidates per point (8 for a grid).
    """
    visibility = _with_visibility(method)
    index, dt = _prepare(lf, points, index, bounds)
    bias = jnp.asarray(normal_bias * probe_spacing(lf, index) if visibility else 0.0, dt)
    fn = lambda x, n: _weights_chunk(lf, index, x.astype(dt), n.astype(dt), bias, visibility)
    none = (jnp.zeros((0, 1), jnp.int32), jnp.zeros((0, 1), dt))
    ids, w = _chunked(fn, points, normals, chunk, empty=none)
    return np.asarray(ids), np.asarray(w)


def shade_irradiance(
    lf: LightFieldProbes,
    points: Float[Array, "n 3"],
    normals: Float[Array, "n 3"],
    *,
    method: str = "lightfield",
    index: GridIndex | VoxelIndex | None = None,
    bounds: Float[Array, "2 3"] | None = None,
    **kw,
) -> Float[Array, "n 3"]:
    """Irradiance by shading method: ``"lightfield"`` (McGuire weights with visibility),
    ``"irradiance"`` (classic probes, no visibility), ``"sh"`` (SH L2)."""
    visibility = _with_visibility(method)
    if method == "sh":
        return sh_irradiance(lf, points, normals, index=index, bounds=bounds, **kw)
    return diffuse_irradiance(lf, points, normals, visibility=visibility, index=index, bounds=bounds, **kw)


def _with_visibility(method: str) -> bool:
    """Whether shading ``method`` weighs probes by visibility (``"lightfield"``: McGuire's Chebyshev
    test); refuses a method not in :data:`SHADINGS`. One rule for the shading and its weights."""
    if method not in SHADINGS:
        raise ConfigError(f"shading method must be one of {SHADINGS}, got {method!r}")
    return method == "lightfield"


__all__ = [
    "SHADINGS",
    "default_index",
    "diffuse_irradiance",
    "glossy_radiance",
    "irradiance_weights",
    "probe_spacing",
    "sh_coefficients",
    "sh_irradiance",
    "shade_irradiance",
]
