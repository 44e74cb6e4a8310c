"""The probes' packed normal maps (``_core.maths._packed``) against a float64 oracle."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import pack_normal, unpack_normal


def _angle64(a, b) -> np.ndarray:
    """Angle between unit vectors in float64, by atan2 (arccos of a float32 dot cannot resolve 1e-4)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


@pytest.mark.isa
def test_normals_round_trip_within_the_snorm16_step():
    """uv is rounded to half of 1/32767 per component; the direction moves by at most that times
    |∂ω/∂uv| (≤ √2·√3 ≈ 2.5 where the octahedron is nearest the origin): ≈ 5e-5 rad, 6.4e-5 measured
    over 200k directions; asserted below 1e-4 with float32 decoding's own rounding beside."""
    rng = np.random.default_rng(0)
    n = rng.normal(size=(20000, 3))
    n[:6] = np.concatenate([np.eye(3), -np.eye(3)])  # the octahedron's corners and folds
    n[6:12] = [[1, 1, 0], [-1, 1, 0], [0, 1, -1], [1, 0, -1], [0, -1, -1], [-1, 0, 1]]
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    packed = pack_normal(jnp.asarray(n, jnp.float32))
    assert packed.dtype == jnp.int16 and packed.shape == (20000, 2)
    back = np.asarray(unpack_normal(packed, jnp.zeros(20000, bool)))
    assert np.abs(np.linalg.norm(back, axis=-1) - 1).max() < 1e-6
    assert _angle64(back, n).max() < 1e-4


def test_escaped_texels_read_back_as_zero_normals():
    """The bake writes zero normals where a texel's ray escapes; they pack (as +z) and read back as zero."""
    n = jnp.asarray([[0.0, 0.0, 0.0], [0.0, -1.0, 0.0]], jnp.float32)
    packed = pack_normal(n)
    np.testing.assert_array_equal(np.asarray(packed)[0], [0, 0])  # +z: the octahedron's centre
    out = np.asarray(unpack_normal(packed, jnp.asarray([True, False])))
    np.testing.assert_array_equal(out[0], 0.0)
    assert _angle64(out[1:], [[0.0, -1.0, 0.0]])[0] < 1e-6
