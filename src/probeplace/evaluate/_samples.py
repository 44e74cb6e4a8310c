"""The reference's sample counts chosen from a noise target (issue 33, "Samples from a noise target").

Each scored indirect component has a reference noise floor (docs/evaluate.md) set by one count:

* **diffuse indirect** — the render's variance of the pixel mean, set by ``EvalConfig.spp`` (paths per
  pixel of the reference render);
* **glossy indirect** — the CRN reference's variance given the shared GGX directions, set by
  ``EvalConfig.glossy_ref_spp`` (paths per GGX direction). The render's own glossy indirect is not
  scored (``mse_glossy_indirect_no_crn`` is a contrast), so ``spp`` is not chosen for it.

A count given as ``"auto"`` is chosen per component: a pilot pass at ``pilot_spp`` = p measures the floor
f_p (a mean over pixels of per-pixel sample variances of the mean), its standard error σ_p over the
pixels, and the black image's MSE b_p = mean(ref²). The variance of a mean of s paths is 1/s of one
path's, so the floor at s paths is f(s) = f⁺ · p / s with f⁺ = f_p + 1.645 σ_p, the pilot's floor at its
one-sided 95 % upper bound: per-pixel variances from a few paths are skewed (a pixel's rare bright path is
usually missed), and at 16×16 pixels and 8 paths the pilot's floor fell 0.68–1.27× the 1024-path
truth over six seeds (σ_p/f_p ≈ 0.17; 0.91–1.17× at 32×32, σ_p/f_p ≈ 0.10), enough to miss a target the
point estimate only just met. The black MSE holds the floor too (E[ref²] = μ² + Var), so at s paths it is
b(s) = b_p − f_p + f(s) (b_p − f_p estimates mean(μ²) without bias). The count is the smallest of p and
the powers of two above it with f(s) ≤ target · b(s), at most ``max_spp``
(``_core.smallest_count``); closed form: s ≥ p · f⁺ (1 − target) / (target (b_p − f_p)).

The final pass is a fresh render at the chosen count with the same seed: the renderer draws sample s of
pixel i from (seed, i, s) alone, so the pilot's p paths are the first p of the final's and are traced
again (the renderer has no sample offset to continue from); when the pilot's count is chosen its pass is
the final one. The floor the run reports and judges (``samples.floor_over_black``, ``target_met``) is the
final pass's own, not the pilot's prediction.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Mapping

import numpy as np

from .._core import PILOT_Z, is_auto, json_number, mean_and_se, smallest_count
from ._config import EvalConfig
from ._decompose import pixel_means
from ._metrics import IndirectScores, SampleCounts
from ._steps import CrnReference, PrimarySamples, ReferenceImages, crn_reference, render_reference

log = logging.getLogger(__name__)

#: The scored components whose floor a count sets, and the EvalConfig field of that count.
COUNT_OF = {"diffuse_indirect": "spp", "glossy_indirect": "glossy_ref_spp"}


@dataclasses.dataclass(frozen=True)
class Pilot:
    """What a pilot pass measured for one component: its count, noise floor, the floor's standard error
    over the pixels, black-image MSE, seconds."""

    spp: int
    floor: float
    floor_se: float
    black: float
    seconds: float

    @property
    def floor_upper(self) -> float:
        """The floor at its one-sided 95 % upper bound, f_p + :data:`PILOT_Z` σ_p."""
        return self.floor + PILOT_Z * self.floor_se


@dataclasses.dataclass(frozen=True)
class CountChoice:
    """A count and how it was chosen: ``"fixed"`` (given) or ``"target"`` (from ``pilot``), with the
    floor ÷ black MSE the pilot predicts at it."""

    spp: int
    chosen_by: str
    pilot: Pilot | None = None
    predicted: float | None = None


def predicted_floor_over_black(pilot: Pilot, spp: int) -> float:
    """f(s) / b(s) at ``spp`` paths from the pilot's figures (module docstring); 0 without noise, ``inf``
    when the pilot's image is all noise (b_p ≤ f_p)."""
    f = pilot.floor_upper * pilot.spp / spp
    if f <= 0:
        return 0.0
    b = pilot.black - pilot.floor + f
    return f / b if b > f else math.inf


def choose_count(pilot: Pilot, target: float, cap: int) -> tuple[int, bool]:
    """The chosen count and whether its prediction meets ``target`` (module docstring)."""
    return smallest_count(lambda s: predicted_floor_over_black(pilot, s) <= target, lo=pilot.spp, cap=cap)


def _figures(floor_px: np.ndarray, img: np.ndarray) -> tuple[float, float, float]:
    """(noise floor, its standard error over the pixels, black MSE) from the per-pixel floor (n, 3) and
    the reference image, as ``evaluate.score`` computes the floor and the black MSE."""
    _, se = mean_and_se(floor_px.reshape(-1, 3).mean(axis=1))  # the floor itself: over pixels and RGB
    img = np.asarray(img, np.float64)
    return float(np.mean(floor_px)), se, float(np.mean(img * img))


def _render_floor(ref: ReferenceImages) -> tuple[float, float, float]:
    """:func:`_figures` of the diffuse indirect render."""
    return _figures(ref.variance["diffuse_indirect"], ref.images["diffuse_indirect"])


def _crn_floor(prim: PrimarySamples, crn: CrnReference) -> tuple[float, float, float]:
    """:func:`_figures` of the CRN glossy reference."""
    n, S = prim.width * prim.height, prim.spp
    floor_px = (prim.w_glossy**2 * crn.var_of_mean).reshape(n, S, 3).sum(axis=1) / S**2
    return _figures(floor_px, pixel_means(prim.w_glossy * crn.radiance, n, S))


def _choose(config: EvalConfig, component: str, pass_at, floor_of, seconds_of):
    """A pass of ``component``'s reference at its count (``pass_at(spp)``) and the :class:`CountChoice`:
    the given count, or a pilot and the chosen count (the pilot's pass when it is chosen)."""
    count = getattr(config, COUNT_OF[component])
    if not is_auto(count):
        return pass_at(count), CountChoice(spp=count, chosen_by="fixed")
    first = pass_at(config.pilot_spp)
    pilot = Pilot(config.pilot_spp, *floor_of(first), seconds_of(first))
    spp, met = choose_count(pilot, config.noise_target, config.max_spp)
    predicted = predicted_floor_over_black(pilot, spp)
    ratio = pilot.floor / pilot.black if pilot.black > 0 else math.inf
    text = (
        f"{COUNT_OF[component]} auto: pilot at {pilot.spp}: {component} noise floor {ratio:.3g} of the "
        f"black MSE; {spp} predicts {predicted:.3g} for a target of {config.noise_target:g}"
    )
    if met:
        log.info("%s", text)
    else:
        log.warning("%s: max_spp=%d cannot reach the target, rendering at the cap", text, config.max_spp)
    final = first if spp == pilot.spp else pass_at(spp)
    return final, CountChoice(spp=spp, chosen_by="target", pilot=pilot, predicted=predicted)


def reference_for_target(scene, camera, config: EvalConfig, *, seed: int, caster):
    """``render_reference`` at ``config.spp`` paths per pixel, or at the count chosen for the diffuse
    indirect's noise target; returns (:class:`ReferenceImages`, :class:`CountChoice`)."""

    def pass_at(spp: int) -> ReferenceImages:
        return render_reference(scene, camera, dataclasses.replace(config, spp=spp), seed=seed, caster=caster)

    return _choose(config, "diffuse_indirect", pass_at, _render_floor, lambda r: r.seconds)


def crn_for_target(scene, prim: PrimarySamples, config: EvalConfig, *, seed: int, caster):
    """``crn_reference`` at ``config.glossy_ref_spp`` paths per GGX direction, or at the count chosen for
    the glossy indirect's noise target; returns (:class:`CrnReference`, :class:`CountChoice`)."""

    def pass_at(spp: int):
        t0 = time.perf_counter()
        crn = crn_reference(
            scene, prim, dataclasses.replace(config, glossy_ref_spp=spp), seed=seed, caster=caster
        )
        return crn, time.perf_counter() - t0

    (crn, _), choice = _choose(
        config, "glossy_indirect", pass_at, lambda r: _crn_floor(prim, r[0]), lambda r: r[1]
    )
    return crn, choice


def samples_metrics(
    config: EvalConfig, choices: dict[str, CountChoice], scores: Mapping[str, IndirectScores]
) -> SampleCounts:
    """``metrics.json``'s ``samples`` group (docs/evaluate.md): the counts, how each was chosen, the
    pilot's figures and, for every scored component, the final pass's floor ÷ black MSE (``scores``: the
    evaluation's own records of those components, their ``noise_floor`` and ``mse_black``) and whether all
    meet the target."""
    per = lambda f: {c: json_number(f(choices[c])) for c in COUNT_OF}
    pilot = lambda f: per(lambda ch: None if ch.pilot is None else f(ch.pilot))
    final = {}
    for c in COUNT_OF:
        floor, black = scores[c].noise_floor, scores[c].mse_black
        final[c] = floor / black if black > 0 else (0.0 if floor <= 0 else math.inf)
    met = all(v <= config.noise_target for v in final.values())
    auto = any(ch.chosen_by == "target" for ch in choices.values())
    return SampleCounts(
        noise_target=config.noise_target,
        pilot_spp=config.pilot_spp if auto else None,
        max_spp=config.max_spp if auto else None,
        reference_spp=choices["diffuse_indirect"].spp,
        reference_chosen_by=choices["diffuse_indirect"].chosen_by,
        glossy_ref_spp=choices["glossy_indirect"].spp,
        glossy_ref_chosen_by=choices["glossy_indirect"].chosen_by,
        pilot_floor=pilot(lambda p: p.floor),
        pilot_floor_se=pilot(lambda p: p.floor_se),
        pilot_black=pilot(lambda p: p.black),
        pilot_floor_over_black=pilot(lambda p: p.floor / p.black if p.black > 0 else None),
        pilot_s=pilot(lambda p: p.seconds),
        predicted_floor_over_black=per(lambda ch: ch.predicted),
        floor_over_black={c: json_number(v) for c, v in final.items()},
        target_met=met,
    )
