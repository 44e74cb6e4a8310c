"""Octahedral mapping of the sphere of directions onto a square (Cigolle et al. 2014, "A Survey of
Efficient Representations for Independent Unit Vectors", JCGT 3(2), §3.6, Listing 6), and the
bordered texel layout of the light-field probes (McGuire et al. 2017 §3; the one-texel border of DDGI,
Luo 2022 §4.3.5).

Conventions (used by baking, the light-field tracer and export alike):
- ``uv`` ∈ [−1, 1]²; the octahedron's axis is world **+Z** (Cigolle's convention): the upper hemisphere
  z ≥ 0 maps to the diamond |u| + |v| ≤ 1, the lower hemisphere to the four corner triangles.
- A map of interior resolution R has texel (row i, column j) centred at u = (j + ½)·2/R − 1,
  v = (i + ½)·2/R − 1: column ↔ u, row ↔ v, row 0 at v = −1.
- Stored maps are (R+2)×(R+2): interior texel (i, j) lives at (i+1, j+1); the border ring holds copies
  of the interior texels that are their neighbours *across the fold* of the octahedron. The square's
  edges fold onto themselves: (1 + δ, v) is the direction of (1 − δ, −v), and likewise for the other
  three edges; a corner's neighbour is the diagonally opposite corner texel. With the ring filled,
  bilinear filtering at any direction reads four texels that are true neighbours on the sphere.
- Solid angle: on the upper face the map is the central projection of the plane |x|+|y|+z = 1, so
  dω = du dv / ‖p‖³ with p = (u, v, 1 − |u| − |v|); the fold that makes the lower half preserves area,
  so the same holds there with p the octahedron point the fold maps ``uv`` to.
"""

from __future__ import annotations

from functools import lru_cache, partial

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int, Shaped

from ._math import safe_normalize


def _sign_not_zero(x: Array) -> Array:
    return jnp.where(x >= 0, jnp.ones_like(x), -jnp.ones_like(x))


@jax.jit  # host callers (index building) get one program per shape, not one per operation
def oct_encode(direction: Float[Array, "... 3"]) -> Float[Array, "... 2"]:
    """Unit direction(s) → octahedral ``uv`` ∈ [−1, 1]² (Cigolle 2014, Listing 6 ``float32x3_to_oct``).

    Differentiable almost everywhere (kinks on the octant planes). ``direction`` need not be unit length
    but must be non-zero.
    """
    l1 = jnp.sum(jnp.abs(direction), axis=-1, keepdims=True)
    p = direction[..., :2] / l1
    folded = (1.0 - jnp.abs(p[..., ::-1])) * _sign_not_zero(p)
    return jnp.where(direction[..., 2:3] < 0, folded, p)


def _octahedron_point(uv: Float[Array, "... 2"]) -> Float[Array, "... 3"]:
    """The point of the octahedron |x| + |y| + |z| = 1 that ``uv`` stands for (before normalising)."""
    u, v = uv[..., 0], uv[..., 1]
    z = 1.0 - jnp.abs(u) - jnp.abs(v)
    lower = z < 0
    x = jnp.where(lower, (1.0 - jnp.abs(v)) * _sign_not_zero(u), u)
    y = jnp.where(lower, (1.0 - jnp.abs(u)) * _sign_not_zero(v), v)
    return jnp.stack([x, y, z], axis=-1)


@jax.jit
def oct_decode(uv: Float[Array, "... 2"]) -> Float[Array, "... 3"]:
    """Octahedral ``uv`` ∈ [−1, 1]² → unit direction (Cigolle 2014, Listing 6 ``oct_to_float32x3``)."""
    return safe_normalize(_octahedron_point(uv))


def oct_wrap(uv: Float[Array, "... 2"]) -> Float[Array, "... 2"]:
    """Fold a ``uv`` up to one square-width outside [−1, 1]² back inside, to the same direction.

    Across the edge u = ±1 the map continues mirrored: (±1 + δ, v) ≅ (±1 − δ, −v); likewise for v.
    """
    u, v = uv[..., 0], uv[..., 1]
    out_u = jnp.abs(u) > 1
    u, v = jnp.where(out_u, 2.0 * jnp.sign(u) - u, u), jnp.where(out_u, -v, v)
    out_v = jnp.abs(v) > 1
    u, v = jnp.where(out_v, -u, u), jnp.where(out_v, 2.0 * jnp.sign(v) - v, v)
    return jnp.stack([u, v], axis=-1)


# The map builders below are jitted with their sizes static: called eagerly (bake, tracer set-up) each is one
# compiled program per size instead of one per jnp operation inside it; under an outer jit they inline.
@partial(jax.jit, static_argnames=("res", "dtype"))
def texel_uv(res: int, dtype=jnp.float32) -> Float[Array, "res res 2"]:
    """Centres of the R×R interior texels in ``uv`` (``[..., 0]`` = u along columns, ``[..., 1]`` = v)."""
    c = (jnp.arange(res, dtype=dtype) + 0.5) * (2.0 / res) - 1.0
    vv, uu = jnp.meshgrid(c, c, indexing="ij")
    return jnp.stack([uu, vv], axis=-1)


@partial(jax.jit, static_argnames=("res", "dtype"))
def texel_directions(res: int, dtype=jnp.float32) -> Float[Array, "res res 3"]:
    """Unit direction through the centre of each interior texel."""
    return oct_decode(texel_uv(res, dtype))


@partial(jax.jit, static_argnames=("res", "dtype", "sub"))
def texel_solid_angles(res: int, dtype=jnp.float32, sub: int = 4) -> Float[Array, "res res"]:
    """Solid angle of each interior texel, steradians (sums to 4π).

    Integrates dω = du dv / ‖p‖³ (module docstring) with a ``sub``×``sub`` midpoint rule per texel.
    """
    p = _octahedron_point(texel_uv(res * sub, dtype))
    norm3 = jnp.sum(p * p, axis=-1) ** 1.5
    w = (2.0 / (res * sub)) ** 2 / norm3
    return w.reshape(res, sub, res, sub).sum(axis=(1, 3))


@partial(jax.jit, static_argnames=("res",))
def border_index(res: int) -> tuple[Int[Array, "rb rb"], Int[Array, "rb rb"]]:
    """For each texel of the (R+2)×(R+2) bordered map, the (row, col) of the *interior* texel it holds.

    Interior texels hold themselves; border texels the neighbour across the octahedral fold
    (:func:`oct_wrap` of the border texel's centre), which is the DDGI border layout.
    """
    c = (jnp.arange(res + 2, dtype=jnp.float32) - 0.5) * (2.0 / res) - 1.0  # padded centres
    vv, uu = jnp.meshgrid(c, c, indexing="ij")
    w = oct_wrap(jnp.stack([uu, vv], axis=-1))
    to_idx = lambda x: jnp.clip(jnp.floor((x + 1.0) * (res / 2.0)), 0, res - 1).astype(jnp.int32)
    return to_idx(w[..., 1]), to_idx(w[..., 0])


@jax.jit
def add_border(interior: Shaped[Array, "... res res c"]) -> Shaped[Array, "... rb rb c"]:
    """Pad R×R interior maps (leading batch axes allowed, channel axis last) to (R+2)×(R+2)."""
    res = interior.shape[-2]
    if interior.shape[-3] != res:
        raise ValueError(f"octahedral maps must be square, got {interior.shape[-3:-1]}")
    rows, cols = border_index(res)
    return interior[..., rows, cols, :]


@lru_cache(maxsize=8)
def _border_ring(res: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The border ring of :func:`border_index` as host arrays: (rows, cols) of the ring's texels in the
    bordered map, and (rows, cols) of the bordered texels they copy."""
    rows, cols = (np.asarray(a) for a in border_index(res))
    ring = np.ones((res + 2, res + 2), bool)
    ring[1:-1, 1:-1] = False
    return (*np.nonzero(ring), rows[ring] + 1, cols[ring] + 1)


def fill_border(bordered: np.ndarray) -> np.ndarray:
    """:func:`add_border` on the host, in place: ``bordered`` is (n, R+2, R+2, …) (a NumPy array, any
    trailing channels) with its interior written; its ring is filled from it and it is returned. For
    maps written batch by batch (the bake: a gather of every texel, as ``add_border`` is, took ~1 s of a
    128-probe 512² bake for three maps; the ring is 4(R+1) texels a map)."""
    ring_r, ring_c, src_r, src_c = _border_ring(bordered.shape[1] - 2)
    bordered[:, ring_r, ring_c] = bordered[:, src_r, src_c]
    return bordered


def strip_border(bordered: Shaped[Array, "... rb rb c"]) -> Shaped[Array, "... res res c"]:
    """Inverse of :func:`add_border`: the interior texels."""
    return bordered[..., 1:-1, 1:-1, :]


def sample_bilinear(bordered: Float[Array, "rb rb c"], direction: Float[Array, "3"]) -> Float[Array, " c"]:
    """Bilinearly filtered value of ONE bordered map in one direction (vmap for batches).

    The four texels read are always inside the (R+2)² array: the border ring supplies the neighbours
    across the fold, so the result is continuous over the whole sphere.
    """
    res = bordered.shape[0] - 2
    uv = oct_encode(direction)
    s = (uv + 1.0) * (res / 2.0) + 0.5  # padded index coordinates; interior centre j ↦ j + 1
    s = jnp.clip(s, 0.5, res + 0.5)
    i0 = jnp.minimum(jnp.floor(s).astype(jnp.int32), res)  # texel centres sit at integer s
    f = s - i0.astype(s.dtype)
    col0, row0 = i0[0], i0[1]
    fu, fv = f[0], f[1]
    a = bordered[row0, col0]
    b = bordered[row0, col0 + 1]
    c = bordered[row0 + 1, col0]
    d = bordered[row0 + 1, col0 + 1]
    return (a * (1 - fu) + b * fu) * (1 - fv) + (c * (1 - fu) + d * fu) * fv


def sample_nearest(bordered: Float[Array, "rb rb c"], direction: Float[Array, "3"]) -> Float[Array, " c"]:
    """Value of the interior texel that contains ``direction`` (no filtering)."""
    row, col = texel_of_direction(bordered.shape[0] - 2, direction)
    return bordered[row + 1, col + 1]


def texel_of_direction(res: int, direction: Float[Array, "3"]) -> Int[Array, "2"]:
    """(row, col) of the interior texel containing ``direction``."""
    uv = oct_encode(direction)
    idx = jnp.clip(jnp.floor((uv + 1.0) * (res / 2.0)), 0, res - 1).astype(jnp.int32)
    return idx[::-1]


def surfel_texels(res: int, geometry_res: int) -> np.ndarray:
    """(res,) int, per axis (rows and columns alike): the texel of a ``geometry_res``² map whose interval
    holds the centre of each texel of a ``res``² map, so radiance texel (r, c) takes its surfel from
    geometry texel (idx[r], idx[c]) (``probes``: the depth-aware read tests that surfel, the bake traces
    the texel's radiance along its direction).

    Integer arithmetic, not ``texel_of_direction`` of the centre direction: when ``geometry_res`` is an
    even multiple of ``res`` the centre lies exactly on a boundary between two geometry texels, where a
    float round trip through the octahedral map picks either side by the last bit (and by the CPU's
    instruction set). Centre i sits at (i + ½)·G / R in geometry texels; its texel is
    ⌊(2i + 1)·G / 2R⌋, the upper one on a boundary."""
    return (2 * np.arange(res) + 1) * geometry_res // (2 * res)


@partial(jax.jit, static_argnames=("res", "geometry_res", "dtype"))
def surfel_directions(res: int, geometry_res: int, dtype=jnp.float32) -> Float[Array, "res res 3"]:
    """The direction of each ``res``² texel's surfel: the centre direction of its geometry texel
    (:func:`surfel_texels`) — where the read's surfel lies and where a ``"surfel"`` bake traces."""
    idx = surfel_texels(res, geometry_res)
    return texel_directions(geometry_res, dtype)[idx[:, None], idx[None, :]]


@partial(jax.jit, static_argnames=("res", "n_sub", "dtype"))
def jittered_texel_directions(
    res: int, n_sub: int, *, key: jax.Array, dtype=jnp.float32
) -> Float[Array, "res res n_sub_sq 3"]:
    """``n_sub``² stratified, jittered directions per interior texel (uniform in ``uv`` within each stratum).

    Stratified sub-texel jitter for baking (issue 3): the strata tile the texel, so the texel's average
    over them converges to the texel's ``uv``-area average as ``n_sub`` grows.
    """
    jitter = jax.random.uniform(key, (res, res, n_sub, n_sub, 2), dtype)
    k = jnp.arange(n_sub, dtype=dtype)
    sv, su = jnp.meshgrid(k, k, indexing="ij")
    strata = jnp.stack([su, sv], axis=-1)  # (n_sub, n_sub, 2) as (u, v)
    within = (strata[None, None] + jitter) / n_sub  # [0,1)² inside the texel
    corner = texel_uv(res, dtype) - 1.0 / res  # texel's lower-left corner in uv
    uv = corner[:, :, None, None, :] + within * (2.0 / res)
    return oct_decode(uv).reshape(res, res, n_sub * n_sub, 3)
