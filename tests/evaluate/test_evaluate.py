"""evaluate() on a tiny Cornell box configuration: files, metric invariants, common random numbers.

Oracles: invariants of the metrics (finite MSEs, positive noise floors, memory adds up, unresolved share
a fraction), the images' defining relations (full = emission + direct + diffuse + glossy; error = |probe −
reference|) and the purpose of common random numbers: the glossy MSE against the CRN reference is below
the MSE of the same probe image against an independent reference render.
"""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import ConfigError, ProbeSet
from probeplace.evaluate import EvalConfig, evaluate, write_evaluation
from probeplace.geometry import BruteForceCaster
from probeplace.probes import BakeConfig, bake_probes, path_traced_radiance
from probeplace.scene import load_scene

KEYS = (
    "mse_glossy_indirect",
    "noise_floor_glossy_indirect",
    "mse_diffuse_indirect",
    "noise_floor_diffuse_indirect",
    "mse_full",
    "noise_floor_full",
    "light_leak_energy",
    "unresolved_share",
    "shading_s_per_frame",
    "shading_compile_s",
    "memory_bytes",
    "n_probes",
    "view",
    "width",
    "height",
    "shading",
)


@pytest.fixture(scope="module")
def cornell_eval():
    scene = load_scene("cornell_box")
    caster = BruteForceCaster(scene)
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    axes = [(np.arange(3) + 0.5) / 3] * 3
    pos = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3) * (hi - lo) + lo
    probes = ProbeSet(pos_world=jnp.asarray(pos, jnp.float32), active=jnp.ones(len(pos), bool))
    cfg = BakeConfig(
        radiance_res=16, irradiance_res=6, moments_res=8, n_sub=1, probes_per_batch=27, progress=False
    )
    albedo = scene.materials.base_color

    def albedo_lit(o, d, k):
        # Cheap stand-in for a path-traced bake (one compile less): each surface reflects 0.3 × albedo.
        h = caster.closest_hit(o, d)
        rad = jnp.where((h.tri >= 0)[:, None], 0.3 * albedo[jnp.maximum(h.material, 0)], 0.0)
        return rad.astype(o.dtype), jnp.zeros_like(o)

    lf = bake_probes(scene, probes, caster=caster, radiance_fn=albedo_lit, key=jax.random.key(0), config=cfg)
    config = EvalConfig(width=12, height=10, spp=8, glossy_spp=4, glossy_ref_spp=2, timing_repeats=1)
    result = evaluate(scene, lf, view="front", config=config, caster=caster)
    return scene, lf, caster, result


def test_evaluate_writes_all_files(cornell_eval, tmp_path):
    result = cornell_eval[3]
    paths = write_evaluation(result, tmp_path / "eval")
    m = json.loads((tmp_path / "eval" / "metrics.json").read_text())
    for k in KEYS:
        assert k in m, k
    for c in ("diffuse_indirect", "glossy_indirect", "full"):
        for stem in (f"ref_{c}", f"probe_{c}", f"error_{c}", f"error_{c}_false"):
            assert (tmp_path / "eval" / f"{stem}.png").is_file(), stem
    assert (tmp_path / "eval" / "images.exr").is_file()
    assert set(paths) >= {"metrics", "exr"}


def test_metrics_invariants(cornell_eval):
    _, lf, _, result = cornell_eval
    m = result.metrics
    for k in ("mse_glossy_indirect", "mse_diffuse_indirect", "mse_full"):
        assert np.isfinite(m[k]) and m[k] >= 0, k
    for k in ("noise_floor_glossy_indirect", "noise_floor_diffuse_indirect", "noise_floor_full"):
        assert m[k] > 0, k
    assert 0.0 <= m["unresolved_share"] <= 1.0
    assert m["shading_s_per_frame"] > 0 and m["shading_compile_s"] >= 0
    mem = m["memory_bytes"]
    assert mem["total"] == sum(mem["by_map"].values())
    assert mem["per_probe"] * m["n_probes"] == pytest.approx(mem["total"])
    # radiance: n × (R+2)² × 3 float32
    assert mem["by_map"]["radiance"] == lf.pos_world.shape[0] * 18 * 18 * 3 * 4
    assert m["n_probes"] == 27 and (m["width"], m["height"]) == (12, 10)
    # the black-image baseline is the mean square of the reference each MSE is taken against
    im = result.images
    for c in ("glossy_indirect", "diffuse_indirect"):
        ref = np.asarray(im[f"ref_{c}"], np.float64)
        assert m[f"mse_black_{c}"] == pytest.approx(np.mean(ref**2), rel=1e-5), c
        err = np.asarray(im[f"error_{c}"], np.float64)
        assert m[f"mse_{c}"] == pytest.approx(np.mean(err**2), rel=1e-4), c
    json.dumps(m, allow_nan=False)


def test_images_compose(cornell_eval):
    _, _, _, result = cornell_eval
    im = result.images
    for v in im.values():
        assert v.shape == (10, 12, 3) and v.dtype == np.float32
    np.testing.assert_allclose(
        im["probe_full"],
        im["ref_emission"] + im["ref_direct"] + im["probe_diffuse_indirect"] + im["probe_glossy_indirect"],
        rtol=1e-5,
        atol=1e-6,
    )
    for c in ("diffuse_indirect", "glossy_indirect", "full"):
        np.testing.assert_allclose(im[f"error_{c}"], np.abs(im[f"probe_{c}"] - im[f"ref_{c}"]), atol=1e-6)
    # The probe diffuse indirect is non-negative and not all zero in the lit box.
    assert im["probe_diffuse_indirect"].min() >= 0 and im["probe_diffuse_indirect"].max() > 0


def test_common_random_numbers_reduce_glossy_mse(cornell_eval):
    m = cornell_eval[3].metrics
    assert m["mse_glossy_indirect"] < m["mse_glossy_indirect_no_crn"]


def test_bad_config_and_view(cornell_eval):
    scene, lf, caster, _ = cornell_eval
    with pytest.raises(ConfigError):
        EvalConfig(shading="phong")
    with pytest.raises(ConfigError):
        EvalConfig(max_depth=2)
    with pytest.raises(ConfigError):
        evaluate(scene, lf, view="nowhere", config=EvalConfig(width=4, height=4), caster=caster)


@pytest.mark.slow
def test_glossy_mse_approaches_noise_floor_with_fine_probes():
    """With finer probe maps the representation error shrinks, so the CRN glossy MSE gets closer to
    its noise floor (the probe radiance is then limited by the bake's own noise)."""
    scene = load_scene("cornell_box")
    caster = BruteForceCaster(scene)
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    axes = [(np.arange(4) + 0.5) / 4] * 3
    pos = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3) * (hi - lo) + lo
    probes = ProbeSet(pos_world=jnp.asarray(pos, jnp.float32), active=jnp.ones(len(pos), bool))
    ratios = []
    for res in (8, 32):
        cfg = BakeConfig(radiance_res=res, n_sub=1, probes_per_batch=16, progress=False)
        lf = bake_probes(
            scene,
            probes,
            caster=caster,
            radiance_fn=path_traced_radiance(scene, spp=8, caster=caster),
            key=jax.random.key(1),
            config=cfg,
        )
        config = EvalConfig(width=24, height=24, spp=16, glossy_spp=8, glossy_ref_spp=8, timing_repeats=1)
        m = evaluate(scene, lf, view="front", config=config, caster=caster).metrics
        ratios.append(m["mse_glossy_indirect"] / m["noise_floor_glossy_indirect"])
    assert ratios[1] < ratios[0]
