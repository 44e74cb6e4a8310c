"""Pre-filtered probe maps made from a baked radiance/distance map (McGuire et al. 2017 §3, §5.2).

* Irradiance, E(n) = ∫ L(ω) max(0, n·ω) dω, for every receiver normal n on a coarser octahedral map:
  the cosine-convolved "irradiance probe" of McGuire §3 (W m⁻² for L in W m⁻² sr⁻¹; divide by π for the
  radiance a white Lambertian surface would reflect).
* Distance moments, E[r] and E[r²] under a normalised cosine-power lobe max(0, n·ω)^p around n
  (McGuire §5.2: "filter these with a cosine-power lobe to account for aliasing in the discrete distance
  values while avoiding overblurring them"); σ² = E[r²] − E[r]² feeds the Chebyshev visibility test.
* Min/max MIP chains of the radial distance for hierarchical tracing (McGuire §4 uses a min-MIP;
  Wang 2019 §4.2 hi-Z uses both bounds).

All integrals are sums over the source map's texels weighted by their exact solid angles
(:func:`~probeplace._core.texel_solid_angles`), so they are quadratures of the stated integrals, not
approximations of unknown bias.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._core import texel_directions, texel_solid_angles


def _lobe_matrix(src_res: int, dst_res: int, power: float | None, dtype) -> Float[Array, "m k"]:
    """(dst texels, src texels) weights: max(0, n·ω)^power · Δω (power None → plain cosine)."""
    omega = texel_directions(src_res, dtype).reshape(-1, 3)
    d_omega = texel_solid_angles(src_res, dtype).reshape(-1)
    normals = texel_directions(dst_res, dtype).reshape(-1, 3)
    cos = jnp.maximum(normals @ omega.T, 0.0)
    if power is not None:
        cos = cos**power
    return cos * d_omega[None, :]


# Jitted with the sizes static: one compiled program per map size instead of one per jnp operation (issue 32).
@partial(jax.jit, static_argnames=("res",))
def irradiance_map(radiance: Float[Array, "p r r 3"], res: int) -> Float[Array, "p res res 3"]:
    """Cosine-convolved irradiance for receiver normals on a ``res``² map, from interior radiance maps."""
    p, r = radiance.shape[0], radiance.shape[1]
    w = _lobe_matrix(r, res, None, radiance.dtype)
    e = jnp.einsum("mk,pkc->pmc", w, radiance.reshape(p, r * r, 3))
    return e.reshape(p, res, res, 3)


@partial(jax.jit, static_argnames=("res", "power"))
def distance_moments(distance: Float[Array, "p r r"], res: int, power: float) -> Float[Array, "p res res 2"]:
    """(E[r], E[r²]) under the normalised lobe max(0, n·ω)^power, for normals on a ``res``² map."""
    p, r = distance.shape[0], distance.shape[1]
    w = _lobe_matrix(r, res, power, distance.dtype)
    w = w / jnp.sum(w, axis=1, keepdims=True)
    d = distance.reshape(p, r * r)
    m1 = d @ w.T
    m2 = (d * d) @ w.T
    return jnp.stack([m1, m2], axis=-1).reshape(p, res, res, 2)
