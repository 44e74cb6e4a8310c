"""Energy: with the one depth rule (``probes.bake_depth_for``), probe-shaded indirect light has the
reference's mean over the image (issue 16).

Oracle. In a *furnace* — a closed box whose walls all emit L_e and reflect albedo ρ — the radiance
reflected by the walls is (nearly) the same everywhere and in every direction (≈ ρL_e(1 + ρ) for texel
paths of three segments, bake depth 3 = camera depth 4 − 1; the dielectric specular lobe of the
evaluation's materials makes it slightly view dependent). So probes have (almost) no representational
error there, and the image means of probe-shaded and reference indirect light must agree within noise.
A bake at another depth cannot pass: depth 7 (the old default, whatever the evaluation's depth) stores
≈ ρL_e(1 + ρ + … + ρ⁶), +32 %; depth 2, −33 %.

Tolerance: ``K_SIGMA`` standard errors of the mean difference, from

* the pixel scatter of the paired difference probe − reference (reference path noise, the probe
  image's sampling noise, per-pixel representation error; pixels independent): std / √pixels;
* the bake's common-mode noise (pixels that read the same probes share it): the spread of the baked
  values (irradiance texels for diffuse, radiance texels for glossy) over all texels of all usable
  probes, which share one expectation in the furnace, divided by √(usable probes): the image reads all
  of them (the view sees five walls; glossy rays reach all six) and each probe's texels are baked
  independently. Reads spread over many texels of each probe only lower it.

The light-field *trace* (glossy rays) must not lose energy either: no ray can leave a closed box, so a
miss is an error. It is checked against the *perfect trace* (exact hit, radiance read from the same probes
there: the same baked texels, so the bake noise cancels). Before the tracer bounded a corner texel by both
walls' planes (``probes.tracer._march._partners``) 7 % of the furnace's glossy rays slipped out as misses
(−6.9 % glossy energy); now −0.6 %, within the noise.

Slow cases (scenes with one emitter, where probes do have representational error) are at the end.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import ProbeSet, strip_border
from probeplace.evaluate import EvalConfig, evaluate
from probeplace.probes import BakeConfig, bake_depth_for, bake_probes, path_traced_radiance
from probeplace.render import default_caster
from probeplace.scene import build_scene, load_scene, make_camera, make_materials
from probeplace.scene._primitives import box

# 4σ: a two-sided normal tail of 6e-5; the figures are deterministic (fixed seeds), so this only says
# how large a bias must be, relative to the noise, to count as one.
K_SIGMA = 4.0
EVAL_DEPTH = 4  # camera segments: the indirect components have paths of 2 and 3 bounces
RHO, LE = 0.5, 1.0  # the furnace's albedo and emitted radiance
L_REFLECTED = RHO * LE * (1 + RHO)  # ≈ its reflected radiance with texel paths of 3 segments


def _grid(scene, n: int) -> ProbeSet:
    """n×n×n probes at the cell centres of the scene's bounding box."""
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    ax = [(np.arange(n) + 0.5) / n] * 3
    pos = np.stack(np.meshgrid(*ax, indexing="ij"), -1).reshape(-1, 3) * (hi - lo) + lo
    return ProbeSet(pos_world=jnp.asarray(pos, jnp.float32), active=jnp.ones(len(pos), bool))


def _closed_box(*, light: bool):
    """A closed 2 m box, walls facing in, Lambert albedo 0.5, a camera inside. ``light=False``: every wall
    emits 1 (the furnace); ``light=True``: dark walls and one emitting 0.6 m square under the ceiling."""
    v, f = box((0.0, 0.0, 0.0), (2.0, 2.0, 2.0))
    f = f[:, ::-1]
    cam = make_camera((1.0, 1.0, 0.05), (1.0, 0.9, 2.0), 80.0, "inside")
    if not light:
        mats = make_materials(["wall"], np.full((1, 3), RHO), emission=np.full((1, 3), LE))
        return build_scene("furnace", v, f, np.zeros(len(f), int), mats, views=(cam,))
    lv = np.array([[0.7, 1.98, 0.7], [1.3, 1.98, 0.7], [1.3, 1.98, 1.3], [0.7, 1.98, 1.3]])
    lf_ = np.array([[0, 1, 2], [0, 2, 3]])  # facing −Y, into the box
    mats = make_materials(
        ["wall", "light"], np.array([[0.5] * 3, [0.0] * 3]), emission=np.array([[0.0] * 3, [10.0] * 3])
    )
    mat = np.r_[np.zeros(len(f), int), np.ones(2, int)]
    return build_scene(
        "box_light", np.concatenate([v, lv]), np.concatenate([f, lf_ + len(v)]), mat, mats, views=(cam,)
    )


def _bake_and_evaluate(scene, view: str, n_grid: int, *, width=24, spp=32, res=8, bake_spp=8, seed=0):
    caster = default_caster(scene)
    lf = bake_probes(
        scene,
        _grid(scene, n_grid),
        caster=caster,
        radiance_fn=path_traced_radiance(
            scene, spp=bake_spp, max_depth=bake_depth_for(EVAL_DEPTH), caster=caster
        ),
        key=jax.random.key(seed),
        config=BakeConfig(
            radiance_res=res, irradiance_res=8, moments_res=8, n_sub=2, probes_per_batch=64, progress=False
        ),
    )
    config = EvalConfig(
        width=width,
        height=width,
        spp=spp,
        glossy_spp=4,
        glossy_ref_spp=2,
        max_depth=EVAL_DEPTH,
        timing_repeats=1,
        bootstrap_resamples=10,
        seed=seed,
    )
    return lf, evaluate(scene, lf, view=view, config=config, caster=caster)


def _means(result, probe: str, ref: str):
    """(probe mean, reference mean, standard error of the paired difference's pixel mean)."""
    p = np.asarray(result.images[probe], np.float64)
    q = np.asarray(result.images[ref], np.float64)
    d = (p - q).mean(axis=-1).reshape(-1)
    return float(p.mean()), float(q.mean()), float(d.std(ddof=1) / np.sqrt(d.size))


def _bake_noise(lf, name: str) -> float:
    """Relative common-mode bake noise of an image mean that reads map ``name`` (module docstring): the
    relative spread of its interior texels over all usable probes / √(usable probes)."""
    usable = np.asarray(lf.active) & ~np.asarray(lf.inside)
    v = np.asarray(strip_border(getattr(lf, name)), np.float64)[usable].mean(axis=-1).reshape(-1)
    return float(v.std(ddof=1) / v.mean() / np.sqrt(usable.sum()))


@pytest.fixture(scope="module")
def furnace():
    return _bake_and_evaluate(_closed_box(light=False), "inside", 4, bake_spp=16)


def _assert_within_noise(probe: float, ref: float, se_px: float, bake_rel: float, what: str) -> None:
    se = float(np.hypot(se_px, bake_rel * ref))
    msg = (
        f"{what}: probe mean {probe:.5g} vs reference {ref:.5g} ({(probe / ref - 1) * 100:+.2f} %), "
        f"tolerance {K_SIGMA}σ = {K_SIGMA * se:.3g} (pixel σ {se_px:.3g}, bake σ {bake_rel * ref:.3g})"
    )
    print(msg)  # the figures, with pytest -s
    assert abs(probe - ref) <= K_SIGMA * se, msg


def test_furnace_diffuse_indirect_energy(furnace):
    lf, result = furnace
    assert result.metrics["n_probes_usable"] == 64
    assert int(lf.bake.path_depth) == bake_depth_for(EVAL_DEPTH) == 3
    p, q, se = _means(result, "probe_diffuse_indirect", "ref_diffuse_indirect")
    _assert_within_noise(p, q, se, _bake_noise(lf, "irradiance"), "diffuse indirect")
    # the reference itself: ≈ ρ_d · ρL_e(1 + ρ), ρ_d the receiver's diffuse albedo (< ρ by Fresnel)
    assert 0.8 * RHO * L_REFLECTED < q < RHO * L_REFLECTED


def test_furnace_glossy_energy_of_the_perfect_trace(furnace):
    """The exact hit, with the probes' radiance there: the bake and the depth rule, without the trace.
    Probes store the view-independent radiance (the diffuse lobe where the texel's ray lands,
    ``probes.path_traced_radiance``), so they are held to the reference with the diffuse lobe only where
    the glossy ray lands; the full reference is brighter by that wall's specular reflection, which the
    evaluation reports as ``mse_glossy_view_dependence``."""
    lf, result = furnace
    assert lf.bake.first_hit_lobes == "diffuse"
    p, q, se = _means(result, "perfect_trace_glossy_indirect", "ref_glossy_indirect_diffuse_at_hit")
    _assert_within_noise(p, q, se, _bake_noise(lf, "radiance"), "glossy indirect (perfect trace)")
    full, view_indep, _ = _means(result, "ref_glossy_indirect", "ref_glossy_indirect_diffuse_at_hit")
    # the walls' dielectric specular lobe (F₀ = 0.04) adds a few per cent, never less, never ≫ 10 %
    assert 1.0 < full / view_indep < 1.12, (full, view_indep)


def test_furnace_glossy_energy_of_the_light_field_trace(furnace):
    _, result = furnace
    p, q, se = _means(result, "probe_glossy_indirect", "perfect_trace_glossy_indirect")
    _assert_within_noise(p, q, se, 0.0, "glossy indirect (light-field trace vs perfect trace)")


# ---- scenes with one emitter: probes have representational error there


@pytest.mark.slow
def test_one_emitter_box_diffuse_bias_is_representational():
    """With one emitter the indirect field varies, and probes a quarter cell from the walls miss the
    darkening of the receivers' near field (corners, wall–floor junctions): the probe image is too bright
    (measured +6.5 % with 4³ probes, +4.1 % with 6³, ≫ the noise). The probes' own irradiance matches a
    path-traced one at their positions within the bake noise (±3 %), so this is the representation, not
    lost or added energy: it must shrink as the probes get closer to the walls."""
    scene = _closed_box(light=True)
    rel = {}
    for n in (4, 6):
        lf, result = _bake_and_evaluate(scene, "inside", n)
        p, q, se = _means(result, "probe_diffuse_indirect", "ref_diffuse_indirect")
        rel[n] = (p - q) / q
        print(
            f"one emitter, {n}³ probes: diffuse {p:.5g} vs {q:.5g} ({rel[n] * 100:+.2f} %), pixel σ {se:.3g}"
        )
        # documented allowance: the measured representational bias (≤ 6.5 %) plus the noise
        assert abs(p - q) <= 0.08 * q + K_SIGMA * np.hypot(se, _bake_noise(lf, "irradiance") * q), n
    assert 0 < rel[6] < 0.8 * rel[4], rel


@pytest.mark.slow
def test_cornell_box_diffuse_indirect_energy():
    """The built-in Cornell box, 4³ probes (those in the blocks are inside and unused), the front view:
    measured +3.5 % at 1.8σ of the pixel noise, i.e. within the noise at this size. The same
    representational allowance as the one-emitter box applies (the probes sit a quarter cell from the
    walls), documented, not fitted."""
    scene = load_scene("cornell_box")
    lf, result = _bake_and_evaluate(scene, "front", 4)
    assert 0 < result.metrics["n_probes_usable"] < 64  # the blocks' probes are inside
    p, q, se = _means(result, "probe_diffuse_indirect", "ref_diffuse_indirect")
    print(f"Cornell box: diffuse {p:.5g} vs {q:.5g} ({(p / q - 1) * 100:+.2f} %), pixel σ {se:.3g}")
    assert abs(p - q) <= 0.08 * q + K_SIGMA * np.hypot(se, _bake_noise(lf, "irradiance") * q)
    g, r, se_g = _means(result, "perfect_trace_glossy_indirect", "ref_glossy_indirect")
    print(
        f"Cornell box: glossy (perfect trace) {g:.5g} vs {r:.5g} ({(g / r - 1) * 100:+.2f} %), σ {se_g:.3g}"
    )
