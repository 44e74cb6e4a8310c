"""The probes' normal maps in two 16-bit components, as compact engines store them.

A unit normal needs only two components in the octahedral parameterisation (Cigolle et al. 2014), here
snorm16 each: 4 bytes a texel instead of 12. With the float32 distance that is 8 bytes a geometry texel
instead of 16: what lets a Sponza 16×8×8 grid's maps (1024 probes at 512²) fit in memory (issue 33).

Why the distance stays float32 although Wang et al. 2019 §5 store R16F: tried (float16 of the distance
over a power-of-two scale, issue 33), the light-field tracer's neighbour tests between adjacent surfels
(``probes.tracer._surfels``: creases, ambiguous cells, ``edge_tol``) read float16's 4.9e-4 relative rounding
as steps between texels of one plane — a single probe in a closed room resolved 85 % of rays on its planar
walls instead of over 94 % (``tests/probes/test_trace.py::test_single_probe_hits_planar_walls_exactly``).

- **Normal**: octahedral ``uv`` (``oct_encode``) rounded to int16 (× 32767); read back with
  ``oct_decode``. Quantisation step 1/32767 in uv: under 1e-4 rad (``tests/core/test_packed.py``).
  Escaping texels hold no surface: their normal reads back as zeros, as the bake writes it.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float, Int

from ._octahedral import oct_decode, oct_encode

#: snorm16's largest magnitude (uv ∈ [−1, 1] ↦ [−32767, 32767], DirectX / glTF snorm rule).
_SNORM16 = 32767.0


@jax.jit
def pack_normal(normal: Float[Array, "... 3"]) -> Int[Array, "... 2"]:
    """Unit normals → octahedral snorm16 pairs; a zero normal (no surface) is stored as +z."""
    n = jnp.asarray(normal, jnp.float32)
    n = jnp.where(jnp.any(n != 0, axis=-1, keepdims=True), n, jnp.array([0.0, 0.0, 1.0], jnp.float32))
    return jnp.round(jnp.clip(oct_encode(n), -1.0, 1.0) * _SNORM16).astype(jnp.int16)


@jax.jit
def unpack_normal(packed: Int[Array, "... 2"], escaped: Array) -> Float[Array, "... 3"]:
    """Inverse of :func:`pack_normal` (float32 unit vectors), zeros where ``escaped`` (the texel's ray
    left the scene: its distance is ``far``)."""
    n = oct_decode(packed.astype(jnp.float32) / _SNORM16)
    return jnp.where(escaped[..., None], 0.0, n)
