"""Math helpers: NaN-safe functions whose values *and* gradients stay finite at the kinks (STYLE §5),
and the power-of-two bucket sizes that host code pads batches to."""

from __future__ import annotations

import operator
from typing import SupportsIndex

import jax.numpy as jnp
from jaxtyping import Array, Float

from ._colour import REC709_LUMA


def safe_norm(v: Float[Array, "... d"], tiny: float = 1e-12) -> Float[Array, "..."]:
    """Euclidean norm whose gradient at 0 is 0 instead of NaN."""
    sq = jnp.sum(v * v, axis=-1)
    small = sq < tiny
    return jnp.where(small, 0.0, jnp.sqrt(jnp.where(small, 1.0, sq)))


def safe_normalize(v: Float[Array, "... d"], tiny: float = 1e-12) -> Float[Array, "... d"]:
    """v / |v|, and 0 for a zero vector (finite gradient either way)."""
    sq = jnp.sum(v * v, axis=-1, keepdims=True)
    small = sq < tiny
    inv = jnp.where(small, 0.0, 1.0 / jnp.sqrt(jnp.where(small, 1.0, sq)))
    return v * inv


def dot3(a: Float[Array, "... 3"], b: Float[Array, "... 3"]) -> Float[Array, "..."]:
    """a·b over a last axis of three, the products summed as written: XLA:CPU vectorises this across the
    leading axes, but not ``jnp.sum(a * b, axis=-1)``'s reduction over a minor axis of 3 (6× slower on
    (1024², 3) arrays; issue 33's tracer set-up)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def norm3(v: Float[Array, "... 3"]) -> Float[Array, "..."]:
    """|v| over a last axis of three (:func:`dot3`'s layout; not safe at 0 for gradients: ``safe_norm``)."""
    return jnp.sqrt(dot3(v, v))


def safe_sqrt(x: Float[Array, "..."]) -> Float[Array, "..."]:
    """sqrt(max(x, 0)) with a finite gradient at 0."""
    pos = x > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, x, 1.0)), 0.0)


def luminance(rgb: Float[Array, "... 3"]) -> Float[Array, "..."]:
    """Rec. 709 relative luminance of linear RGB (:data:`REC709_LUMA`)."""
    w = jnp.asarray(REC709_LUMA, rgb.dtype)
    return rgb @ w


def next_pow2(n: SupportsIndex, *, lo: int = 1, hi: int | None = None) -> int:
    """The smallest power of two ≥ ``n`` (1 for ``n`` ≤ 1), raised to at least ``lo``, then capped at ``hi``.

    Host helper for padding a batch before a jitted call: varying counts fall into a few sizes, so the
    code compiles a few times instead of once per count. ``hi`` (a chunk limit) need not be a power of two.

    Args:
        n: the count to pad (an ``int`` or a NumPy integer).
        lo: the smallest size returned (unless ``hi`` is smaller).
        hi: the largest size returned, or ``None`` for no cap.
    """
    p = max(lo, 1 << max(operator.index(n) - 1, 0).bit_length())
    return p if hi is None else min(hi, p)


def padded_count(n: SupportsIndex, *, lo: int, step: int) -> int:
    """A batch of ``n`` padded to one of a few sizes: a power of two from ``lo`` up to ``step``, then a
    multiple of ``step`` (at most twice ``n`` below ``step``, under ``step`` more above it).

    Host helper, as :func:`next_pow2`, for counts that may grow past what doubling should pad (probe
    rows, host ray batches). ``step`` is a power of two ≥ ``lo``.
    """
    n = operator.index(n)
    return next_pow2(n, lo=lo) if n <= step else -(-n // step) * step
