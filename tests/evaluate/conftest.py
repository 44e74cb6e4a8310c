"""Fixtures shared by the evaluation's tests."""

from __future__ import annotations

import jax
import pytest

from probeplace.evaluate import EvalConfig
from probeplace.geometry import BruteForceCaster
from probeplace.probes import BakeConfig, bake_probes
from probeplace.scene import load_scene
from tests.helpers import albedo_lit, grid_probe_set


@pytest.fixture(scope="module")
def cornell():
    """(scene, baked probes, caster, base EvalConfig): the Cornell box, a 2×2×2 grid baked at 8² and a
    16×16 evaluation without sample counts (``test_samples.py``, ``test_metrics_keys.py``)."""
    scene = load_scene("cornell_box")
    caster = BruteForceCaster(scene)
    probes = grid_probe_set(scene, (2, 2, 2))
    cfg = BakeConfig(
        radiance_res=8, irradiance_res=4, moments_res=4, n_sub=1, probes_per_batch=8, progress=False
    )
    # a stand-in for a path-traced bake: the probes' radiance does not enter the reference's noise, which
    # is what test_samples.py tests
    radiance = albedo_lit(scene, caster)
    lf = bake_probes(scene, probes, caster=caster, radiance_fn=radiance, key=jax.random.key(0), config=cfg)
    base = EvalConfig(
        width=16, height=16, glossy_spp=4, max_depth=4, timing_repeats=1, bootstrap_resamples=20
    )
    return scene, lf, caster, base


def evaluation_steps(scene, lf, caster, config):
    """The evaluation's steps, as ``evaluate`` runs them at ``config``'s fixed counts: the arguments of
    ``score`` after ``config`` (seed, reference, primary samples, CRN reference, shading, perfect trace)."""
    from probeplace.evaluate import (
        crn_reference,
        perfect_trace,
        render_reference,
        sample_primary,
        shade_probes,
    )
    from probeplace.probes import glossy_maps

    camera, seed = scene.view("front"), int(config.seed)
    ref = render_reference(scene, camera, config, seed=seed, caster=caster)
    prim = sample_primary(scene, camera, config, seed=seed, caster=caster)
    crn = crn_reference(scene, prim, config, seed=seed, caster=caster)
    maps = glossy_maps(lf, config.glossy_filter, include_emission=False)
    shading = shade_probes(scene, lf, prim, config, maps=maps)
    perfect = perfect_trace(lf, prim, config, caster=caster, maps=maps)
    return seed, ref, prim, crn, shading, perfect
