"""BRDF tests: closed forms, reciprocity, white furnace, sampling ⇔ pdf consistency (quadrature)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace.render import BrdfParams, eval_brdf, pdf_brdf, sample_brdf


def _params(base=(0.8, 0.6, 0.3), rough=0.5, metal=0.0, spec=1.0, dtype=jnp.float64):
    return BrdfParams(
        base_color=jnp.asarray(base, dtype),
        roughness=jnp.asarray(rough, dtype),
        metallic=jnp.asarray(metal, dtype),
        specular=jnp.asarray(spec, dtype),
    )


def _dir(theta, phi=0.3):
    return jnp.asarray([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])


def _sphere_grid(n_theta=400, n_phi=400):
    """Midpoint quadrature over the whole sphere: directions (N, 3) and solid-angle weights (N,)."""
    th = (np.arange(n_theta) + 0.5) * np.pi / n_theta
    ph = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    t, p = np.meshgrid(th, ph, indexing="ij")
    d = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    w = (np.sin(t) * (np.pi / n_theta) * (2 * np.pi / n_phi)).reshape(-1)
    return jnp.asarray(d), w


def _eval_many(p, wo, wi):
    return jax.vmap(eval_brdf, in_axes=(None, None, 0))(p, wo, wi)


def test_lambert_closed_form():
    # metallic 0, specular 0: pure Lambert c/π for any pair of upper-hemisphere directions.
    p = _params(spec=0.0)
    for a, b in [(0.1, 0.7), (1.2, 0.4), (0.0, 1.5)]:
        f_d, f_s = eval_brdf(p, _dir(a), _dir(b, 2.0))
        np.testing.assert_allclose(f_d, np.array([0.8, 0.6, 0.3]) / np.pi, rtol=1e-12)
        np.testing.assert_allclose(f_s, 0.0, atol=0)
    # Below the horizon: zero.
    f_d, f_s = eval_brdf(p, _dir(0.3), _dir(2.0))
    assert float(jnp.max(f_d + f_s)) == 0.0


@pytest.mark.parametrize("rough,metal", [(0.05, 0.0), (0.3, 0.5), (0.7, 1.0), (1.0, 0.0)])
def test_reciprocity(rough, metal, getkey):
    p = _params(rough=rough, metal=metal)
    a = jax.random.normal(getkey(), (200, 3), jnp.float64)
    b = jax.random.normal(getkey(), (200, 3), jnp.float64)
    a = a.at[:, 2].set(jnp.abs(a[:, 2]))
    b = b.at[:, 2].set(jnp.abs(b[:, 2]))
    a = a / jnp.linalg.norm(a, axis=1, keepdims=True)
    b = b / jnp.linalg.norm(b, axis=1, keepdims=True)
    fab = jax.vmap(eval_brdf, in_axes=(None, 0, 0))(p, a, b)
    fba = jax.vmap(eval_brdf, in_axes=(None, 0, 0))(p, b, a)
    for x, y in zip(fab, fba, strict=True):
        # Same formula with arguments swapped: equal up to float64 round-off in the half vector.
        np.testing.assert_allclose(x, y, rtol=1e-9, atol=1e-12)


def test_white_furnace_lambert_sampling_weight_is_one(getkey):
    # Cosine sampling of a white Lambertian: f cos / pdf = 1 exactly for every sample.
    p = _params(base=(1.0, 1.0, 1.0), spec=0.0)
    u = jax.random.uniform(getkey(), (500, 3), jnp.float64)
    s = jax.vmap(sample_brdf, in_axes=(None, None, 0))(p, _dir(0.6), u)
    np.testing.assert_allclose(s.weight, 1.0, rtol=1e-9)
    np.testing.assert_allclose(s.weight_lobe, 1.0, rtol=1e-9)


@pytest.mark.parametrize("theta_o", [0.2, 0.9, 1.3])
@pytest.mark.parametrize("rough", [0.1, 0.5, 1.0])
def test_white_furnace_ggx(theta_o, rough, getkey):
    # A white metal (F = 1) under VNDF sampling has weight f cos / pdf = G₁(wi) ∈ [0, 1] per sample
    # (Heitz 2018 §3): it never creates energy; the albedo E[G₁(wi)] is near 1 when smooth and drops
    # with roughness (single-scattering GGX loses the multiply-scattered energy; Heitz et al. 2016).
    p = _params(base=(1.0, 1.0, 1.0), rough=rough, metal=1.0)
    u = jax.random.uniform(getkey(), (20_000, 3), jnp.float64)
    s = jax.vmap(sample_brdf, in_axes=(None, None, 0))(p, _dir(theta_o), u)
    wt = np.asarray(s.weight)
    assert np.all(wt <= 1.0 + 1e-9) and np.all(wt >= 0)
    albedo = wt[:, 0].mean()
    se = wt[:, 0].std() / np.sqrt(wt.shape[0])
    if rough <= 0.1:
        assert albedo > 0.97
    else:
        # Independent oracle: the textbook GGX albedo (Walter et al. 2007 Eqs. 20, 33, 34) by NumPy
        # quadrature over the hemisphere (a broad lobe, so a 1000×2000 grid resolves it).
        ref = _textbook_ggx_albedo(rough**2, theta_o)
        assert abs(albedo - ref) < 5 * se + 1e-3, (albedo, ref, se)


def _textbook_ggx_albedo(a, theta_o, n=1000):
    th = (np.arange(n) + 0.5) * (np.pi / 2) / n
    ph = (np.arange(2 * n) + 0.5) * np.pi / n
    t, p = np.meshgrid(th, ph, indexing="ij")
    w = np.sin(t) * (np.pi / 2 / n) * (np.pi / n)
    wi = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    wo = np.array([np.sin(theta_o) * np.cos(0.3), np.sin(theta_o) * np.sin(0.3), np.cos(theta_o)])
    h = wi + wo
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    d = a * a / (np.pi * (h[..., 2] ** 2 * (a * a - 1) + 1) ** 2)
    g1 = lambda c: 2 * c / (c + np.sqrt(a * a * (1 - c * c) + c * c))
    ci = wi[..., 2]
    f = d * g1(ci) * g1(wo[2]) / (4 * ci * wo[2])
    return float(np.sum(f * ci * w))


@pytest.mark.parametrize("rough,metal", [(0.2, 0.0), (0.6, 0.3), (0.9, 1.0)])
def test_pdf_normalised(rough, metal):
    # Each lobe's pdf is a density on the sphere: it integrates to 1 (quadrature oracle).
    # Rough ≥ 0.2 keeps the GGX peak resolvable by the 400×400 grid.
    d, w = _sphere_grid()
    p = _params(rough=rough, metal=metal)
    pd, ps, _ = jax.vmap(pdf_brdf, in_axes=(None, None, 0))(p, _dir(0.5), d)
    np.testing.assert_allclose(np.sum(np.asarray(pd) * w), 1.0, rtol=2e-3)
    np.testing.assert_allclose(np.sum(np.asarray(ps) * w), 1.0, rtol=2e-2)


@pytest.mark.parametrize("rough,metal", [(0.3, 0.0), (0.6, 0.5), (0.4, 1.0)])
def test_importance_sampling_matches_integral(rough, metal, getkey):
    # E[weight] under sample_brdf = ∫ (f_d + f_s) cos dω (quadrature); this checks sampler and pdf agree.
    d, w = _sphere_grid()
    p = _params(rough=rough, metal=metal)
    wo = _dir(0.7)
    f_d, f_s = _eval_many(p, wo, d)
    cos = np.maximum(np.asarray(d[:, 2]), 0)[:, None]
    ref_total = np.sum((np.asarray(f_d) + np.asarray(f_s)) * cos * w[:, None], axis=0)
    ref_d = np.sum(np.asarray(f_d) * cos * w[:, None], axis=0)
    ref_s = np.sum(np.asarray(f_s) * cos * w[:, None], axis=0)
    n = 200_000
    u = jax.random.uniform(getkey(), (n, 3), jnp.float64)
    s = jax.vmap(sample_brdf, in_axes=(None, None, 0))(p, wo, u)
    wt = np.asarray(s.weight)
    wl = np.asarray(s.weight_lobe)
    spec = np.asarray(s.specular)[:, None]
    for est, ref in [
        (wt, ref_total),
        (wl * ~spec, ref_d),  # the per-lobe estimator is unbiased for each lobe separately
        (wl * spec, ref_s),
    ]:
        mean = est.mean(axis=0)
        se = est.std(axis=0) / np.sqrt(n)
        assert np.all(np.abs(mean - ref) <= 5 * se + 2e-3 * ref), (mean, ref, se)
    # The sampled pdf equals the mixture pdf evaluated at the sampled direction.
    pd, ps, pspec = jax.vmap(pdf_brdf, in_axes=(None, None, 0))(p, wo, s.wi)
    np.testing.assert_allclose(s.pdf, (1 - pspec) * pd + pspec * ps, rtol=1e-9)


def test_float32_in_float32_out():
    p = _params(dtype=jnp.float32)
    wo = _dir(0.4).astype(jnp.float32)
    wi = _dir(0.8, 1.0).astype(jnp.float32)
    f_d, f_s = eval_brdf(p, wo, wi)
    s = sample_brdf(p, wo, jnp.asarray([0.3, 0.4, 0.5], jnp.float32))
    assert f_d.dtype == f_s.dtype == s.weight.dtype == s.wi.dtype == jnp.float32
    assert np.all(np.isfinite(np.asarray(s.weight)))
