"""Soft (differentiable) visibility between two points through the SDF.

Binary visibility — "does the segment a→b cross a surface" — has zero gradient almost everywhere, so
the placement fitness (Wang et al. 2019, Eq. 1, whose visibility term is binary) uses a smooth stand-in:

    V(a, b) = σ((m − τ) / s),   m = minᵢ cᵢ,   cᵢ = (f(xᵢ) + f(xᵢ₊₁) − Δ) / 2

with xᵢ evenly spaced points of the segment (spacing Δ), f the SDF (negative inside solids), τ a
thickness below which the segment counts as touching a surface, s the sharpness and σ the logistic
function. cᵢ is a lower bound of the distance from the interval [xᵢ, xᵢ₊₁] to the surface (f is
1-Lipschitz: a point u along the interval is at least max(f(xᵢ) − u, f(xᵢ₊₁) − (Δ − u)) away, whose
minimum over u is cᵢ), so a wall cannot slip between two samples however few there are — the same bound
that makes sphere tracing safe (Hart 1996, "Sphere tracing", §2). Taking the (soft) minimum of a
clearance along the ray is the soft-shadow idea of SDF rendering (Quilez 2010,
https://iquilezles.org/articles/rmshadows/), here with the penumbra fixed in scene units. A hard
minimum, not a log-sum-exp soft-min: the soft-min of N clear intervals sits s·log N below their
clearance (penalising long clear segments), and a normalised one lets one blocked interval be outvoted;
the minimum of smooth functions is differentiable almost everywhere (gradient through the arg-min).

The price of that guarantee: a clear segment that runs within about Δ/2 + τ of a surface reads as
partly blocked, so ``n_steps`` sets the resolution (Δ = (length − 2·margin)/(n_steps − 1)).
Sample positions are fixed fractions of the segment, so V is an ordinary smooth function of a and b and
its gradient is exact (no stop-gradient through adaptive step positions).

Endpoints on surfaces (probes near geometry, surface samples on it) must not count as blocked: the
samples skip ``margin`` at each end. τ defaults to h√3/2 — the largest value the interpolated field
takes on a one-sided sheet, where it is unsigned — so sheets block like solids.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._core import safe_norm
from ._sdf import SDFGrid, sdf_value


def soft_visibility(
    grid: SDFGrid,
    a: Float[Array, "3"],
    b: Float[Array, "3"],
    *,
    sharpness: float | Float[Array, ""],
    n_steps: int,
    margin: float | Float[Array, ""] | None = None,
    thickness: float | Float[Array, ""] | None = None,
) -> Float[Array, ""]:
    """Smooth visibility of b from a: ≈1 when the segment is clear, → 0 as it passes through geometry.

    Differentiable in ``a`` and ``b`` (and the grid values) with finite gradients everywhere, including
    a == b, endpoints on surfaces and segments along a surface.

    Args:
        grid: the SDF.
        a, b: segment endpoints, world frame.
        sharpness: s, scene units: the width of the transition (V = 0.5 at clearance τ, 0.73 at τ + s,
            0.27 at τ − s).
        n_steps: number of samples (static, ≥ 2); see the module docstring for what it resolves.
        margin: length skipped at each end, scene units; default 2·voxel_size.
        thickness: τ, scene units; default voxel_size·√3/2.

    Returns:
        V in [0, 1]; exactly 1 when the segment is no longer than two margins.
    """
    if n_steps < 2:
        raise ValueError(f"n_steps must be at least 2, got {n_steps}")
    dtype = a.dtype
    h = grid.voxel_size.astype(dtype)
    s = jnp.asarray(sharpness, dtype)
    tau = h * jnp.sqrt(jnp.asarray(3.0, dtype)) / 2 if thickness is None else jnp.asarray(thickness, dtype)
    m = 2.0 * h if margin is None else jnp.asarray(margin, dtype)
    seg = b - a
    length = safe_norm(seg)
    inner = length - 2.0 * m
    ok = inner > 0
    inner_safe = jnp.where(ok, inner, 1.0)
    length_safe = jnp.where(ok, length, 1.0)
    delta = inner_safe / (n_steps - 1)
    t = m + delta * jnp.arange(n_steps, dtype=dtype)
    pts = a[None, :] + (t / length_safe)[:, None] * seg[None, :]
    f = jax.vmap(lambda p: sdf_value(grid, p))(pts)
    c = (f[:-1] + f[1:] - delta) / 2.0
    v = jax.nn.sigmoid((jnp.min(c) - tau) / s)
    return jnp.where(ok, v, jnp.ones((), dtype))
