"""Random numbers and sample warps shared by the path tracer, the BRDFs and the probe renderer.

Random numbers are a *pure function* of (seed, pixel, sample index, bounce): the evaluation renders the
probe image with the same sampled directions per pixel as the reference (DESIGN.md "common random
numbers"), so neither renderer may depend on how paths are batched. We hash the four integers with
PCG4D (Jarzynski & Olano 2020, "Hash Functions for GPU Rendering", JCGT 9(3), §3: the 4D PCG variant,
which passes TestU01 BigCrush on such structured inputs) instead of chaining ``jax.random.fold_in``:
it is a few integer multiply-adds instead of a Threefry block per draw, and the path tracer draws
~10 numbers per path per bounce.

Layout of the eight uniforms :func:`path_uniforms` returns for one (pixel, sample, bounce):

=====  ==========================================================================
dim    use
=====  ==========================================================================
0      lobe choice (diffuse vs specular) at the vertex
1, 2   BRDF direction sample (at bounce 0: the sub-pixel jitter of the camera ray)
3      Russian roulette
4      light-type choice (area lights vs sun)
5      emissive-triangle choice
6, 7   point on the triangle / direction in the sun's cone
=====  ==========================================================================

Bounce 0 is the camera ray; bounce k ≥ 1 is the scattering event at the k-th surface hit.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float, Int, Key, UInt32

N_UNIFORMS = 8
DIM_LOBE, DIM_DIR_U, DIM_DIR_V, DIM_RR = 0, 1, 2, 3
DIM_LIGHT_TYPE, DIM_LIGHT_TRI, DIM_LIGHT_U, DIM_LIGHT_V = 4, 5, 6, 7


def seed_from_key(key: Key[Array, ""]) -> UInt32[Array, ""]:
    """A 32-bit seed for :func:`path_uniforms` from a JAX PRNG key."""
    return jax.random.bits(key, (), jnp.uint32)


def pcg4d_lanes(x, y, z, w):
    """Jarzynski & Olano 2020, Listing "pcg4d", on four lanes of any uint32 array type with wrapping
    ``+ * ^ >>`` (JAX here, Dr.Jit in the Mitsuba backend: one definition keeps their streams equal): an
    LCG step, two rounds of cross-lane multiply-adds around an xorshift, as in the GLSL original."""
    x, y, z, w = (v * 1664525 + 1013904223 for v in (x, y, z, w))
    x = x + y * w
    y = y + z * x
    z = z + x * y
    w = w + y * z
    x, y, z, w = x ^ (x >> 16), y ^ (y >> 16), z ^ (z >> 16), w ^ (w >> 16)
    x = x + y * w
    y = y + z * x
    z = z + x * y
    w = w + y * z
    return x, y, z, w


def _pcg4d(v: UInt32[Array, "4"]) -> UInt32[Array, "4"]:
    return jnp.stack(pcg4d_lanes(*(v[i] for i in range(4))))


def _to_unit(bits: UInt32[Array, "..."]) -> Float[Array, "..."]:
    # Top 24 bits → a float32 in [0, 1) exactly representable (never rounds up to 1).
    return (bits >> 8).astype(jnp.float32) * jnp.float32(2.0**-24)


def path_uniforms(
    seed: UInt32[Array, ""], pixel: Int[Array, ""], sample: Int[Array, ""], bounce: Int[Array, ""] | int
) -> Float[Array, "8"]:
    """Eight float32 uniforms in [0, 1) for one (pixel, sample, bounce); see the module docstring.

    A pure function of its inputs (no key splitting), so the reference and the probe renderer draw
    the same numbers for the same pixel sample whatever their batching. Vectorise with ``jax.vmap``.
    """
    p = jnp.asarray(pixel).astype(jnp.uint32)
    s = jnp.asarray(sample).astype(jnp.uint32)
    b = jnp.asarray(bounce).astype(jnp.uint32)
    seed = jnp.asarray(seed).astype(jnp.uint32)
    # Two hashes per bounce (4 numbers each); the group index sits in the bounce word so the eight
    # numbers come from distinct hash inputs.
    lo = _pcg4d(jnp.stack([p, s, b * jnp.uint32(2), seed]))
    hi = _pcg4d(jnp.stack([p, s, b * jnp.uint32(2) + jnp.uint32(1), seed]))
    return _to_unit(jnp.concatenate([lo, hi]))


# --------------------------------------------------------------------------------------------------
# Frames and warps (single instance; vmap at the caller)
# --------------------------------------------------------------------------------------------------


def make_frame(n: Float[Array, "3"]) -> tuple[Float[Array, "3"], Float[Array, "3"]]:
    """Tangent and bitangent completing unit ``n`` to a right-handed orthonormal basis (t, b, n).

    Branch-free and continuous except at n.z = 0 (Duff et al. 2017, "Building an Orthonormal Basis,
    Revisited", JCGT 6(1), Listing 3).
    """
    sign = jnp.where(n[2] >= 0, jnp.asarray(1.0, n.dtype), jnp.asarray(-1.0, n.dtype))
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    t = jnp.stack([1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]])
    bt = jnp.stack([b, sign + n[1] * n[1] * a, -n[1]])
    return t, bt


def dot3(a: Float[Array, "3"], b: Float[Array, "3"]) -> Float[Array, ""]:
    """Dot product of two 3-vectors written out: under vmap this stays an elementwise fusion, where
    ``jnp.dot`` becomes a batched ``dot_general`` that XLA's CPU backend runs as a slow library call."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def to_local(
    v: Float[Array, "3"], t: Float[Array, "3"], b: Float[Array, "3"], n: Float[Array, "3"]
) -> Float[Array, "3"]:
    """World → local coordinates in the frame (t, b, n)."""
    return jnp.stack([dot3(v, t), dot3(v, b), dot3(v, n)])


def to_world(
    v: Float[Array, "3"], t: Float[Array, "3"], b: Float[Array, "3"], n: Float[Array, "3"]
) -> Float[Array, "3"]:
    """Local coordinates in the frame (t, b, n) → world."""
    return v[0] * t + v[1] * b + v[2] * n


def sample_cosine_hemisphere(u: Float[Array, "2"]) -> Float[Array, "3"]:
    """Cosine-weighted direction about +z (Malley's method: uniform disk point lifted to the
    hemisphere; PBRT 4 §A.5.3). Density cosθ/π."""
    r = jnp.sqrt(u[0])
    phi = 2.0 * jnp.pi * u[1]
    z = jnp.sqrt(jnp.maximum(1.0 - u[0], 0.0))
    return jnp.stack([r * jnp.cos(phi), r * jnp.sin(phi), z])


def sample_triangle(u: Float[Array, "2"]) -> Float[Array, "3"]:
    """Barycentrics (b0, b1, b2) of a uniform point on a triangle (Turk 1990 / PBRT 4 §A.5.4 square-root
    map): b0 = 1 − √u₀, b1 = √u₀ (1 − u₁), b2 = √u₀ u₁."""
    su = jnp.sqrt(u[0])
    return jnp.stack([1.0 - su, su * (1.0 - u[1]), su * u[1]])


def sample_cone(u: Float[Array, "2"], one_minus_cos_max: Float[Array, ""]) -> Float[Array, "3"]:
    """Uniform direction in the cone about +z with 1 − cos θmax = ``one_minus_cos_max``.

    Parameterised by h = 1 − cos θmax (not cos θmax) so the sun's 0.27° disk keeps float32
    precision: sin θ = √(uh(2 − uh)) avoids the cancellation in √(1 − cos²θ). Density 1 / (2π h).
    """
    uh = u[0] * one_minus_cos_max
    cos_t = 1.0 - uh
    sin_t = jnp.sqrt(jnp.maximum(uh * (2.0 - uh), 0.0))
    phi = 2.0 * jnp.pi * u[1]
    return jnp.stack([sin_t * jnp.cos(phi), sin_t * jnp.sin(phi), cos_t])


def power_heuristic(pdf_a: Float[Array, "..."], pdf_b: Float[Array, "..."]) -> Float[Array, "..."]:
    """MIS weight of strategy a, β = 2 (Veach 1997, Eq. 9.13); 0 where both densities vanish, and
    finite when a density is inf (a delta strategy wins outright)."""
    a2 = pdf_a * pdf_a
    b2 = pdf_b * pdf_b
    den = a2 + b2
    ok = (den > 0) & jnp.isfinite(den)
    w = jnp.where(ok, a2 / jnp.where(ok, den, 1.0), 0.0)
    return jnp.where(jnp.isinf(pdf_a), 1.0, jnp.where(jnp.isinf(pdf_b), 0.0, w))
