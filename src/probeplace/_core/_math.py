"""NaN-safe math helpers: values *and* gradients stay finite at the kinks (STYLE §5)."""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array, Float


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


def safe_sqrt(x: Float[Array, "..."]) -> Float[Array, "..."]:
    """sqrt(max(x, 0)) with a finite gradient at 0."""
    pos = x > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, x, 1.0)), 0.0)


def luminance(rgb: Float[Array, "... 3"]) -> Float[Array, "..."]:
    """Rec. 709 relative luminance of linear RGB."""
    w = jnp.asarray([0.2126, 0.7152, 0.0722], rgb.dtype)
    return rgb @ w
