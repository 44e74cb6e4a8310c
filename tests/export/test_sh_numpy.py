"""The NumPy octahedral/SH helpers of the exporters equal the JAX originals and closed forms."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from probeplace._core import add_border as jax_add_border
from probeplace._core import sample_bilinear as jax_sample_bilinear
from probeplace._core import texel_directions as jax_texel_directions
from probeplace._core import texel_solid_angles as jax_texel_solid_angles
from probeplace.export import _octa
from probeplace.export._sh import COSINE_LOBE, project_radiance, sh_basis, sh_irradiance


def test_octahedral_helpers_match_core():
    res = 7  # odd: texel centres do not fall on the octahedron's edges
    np.testing.assert_allclose(
        _octa.texel_directions(res), jax_texel_directions(res, jnp.float64), atol=1e-15
    )
    np.testing.assert_allclose(
        _octa.texel_solid_angles(res), jax_texel_solid_angles(res, jnp.float64), rtol=1e-13
    )
    x = np.random.default_rng(res).normal(size=(2, res, res, 3))
    np.testing.assert_array_equal(_octa.add_border(x), np.asarray(jax_add_border(jnp.asarray(x))))


def test_bilinear_sampling_matches_core():
    rng = np.random.default_rng(0)
    maps = _octa.add_border(rng.normal(size=(2, 6, 6, 3)))
    dirs = rng.normal(size=(50, 3))
    got = _octa.sample_bilinear(maps, dirs)
    per_map = jax.vmap(jax_sample_bilinear, in_axes=(None, 0))
    want = np.stack([np.asarray(per_map(jnp.asarray(m), jnp.asarray(dirs))) for m in maps])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_resample_is_identity_at_same_resolution_and_exact_for_constants():
    maps = _octa.add_border(np.random.default_rng(1).normal(size=(1, 4, 4, 2)))
    np.testing.assert_array_equal(_octa.resample_bordered(maps, 4), maps)
    const = np.full((1, 6, 6, 2), 3.25)
    np.testing.assert_allclose(_octa.resample_bordered(const, 9), 3.25, rtol=1e-14)


def test_three_js_constants():
    """three.js shGetIrradianceAt: 0.886227, 2·0.511664, 2·0.429043, 0.743125 / 0.247708, 0.429043."""
    n = np.array([[0.3, -0.5, 0.81]]) / np.linalg.norm([0.3, -0.5, 0.81])
    y = (sh_basis(n) * COSINE_LOBE)[0]
    x_, y_, z_ = n[0]
    want = [0.886227, 1.023328 * y_, 1.023328 * z_, 1.023328 * x_, 0.858086 * x_ * y_, 0.858086 * y_ * z_,
            0.743125 * z_ * z_ - 0.247708, 0.858086 * x_ * z_, 0.429043 * (x_ * x_ - y_ * y_)]  # fmt: skip
    np.testing.assert_allclose(y, want, rtol=2e-5)  # three.js prints 6 digits


def test_sh_of_linear_radiance_gives_closed_form_irradiance():
    """L(ω) = a + b·ω ⇒ E(n) = π a + (2π/3) b·n exactly (Ramamoorthi & Hanrahan 2001, Eq. 8-9).

    The projection is a quadrature over 64² texels; its error for a linear integrand is below 0.1 %
    of the magnitude at this resolution (it shrinks as 1/res²: tested at two resolutions).
    """
    a, b = np.array([1.0, 2.0, 0.5]), np.array([[0.3, -0.2, 0.1], [0.0, 0.4, -0.3], [0.2, 0.2, 0.2]])
    normals = np.random.default_rng(2).normal(size=(30, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    want = np.pi * a + 2 * np.pi / 3 * normals @ b.T
    errs = []
    for res in (32, 64):
        d = _octa.texel_directions(res)
        rad = _octa.add_border(a + d @ b.T)[None]
        got = sh_irradiance(project_radiance(rad), normals)[0]
        errs.append(np.abs(got - want).max() / np.abs(want).max())
    assert errs[1] < 1e-3
    assert errs[1] < errs[0] / 3  # converges like 1/res²
