"""The bake's paths per texel ray chosen from a noise target (issue 33, "Samples from a noise target").

**What is held to the target.** The radiance maps' seed-to-seed noise: a texel's value changes with the
bake's key through two draws, the sub-texel jitter of its ``n_sub``² rays (``BakeConfig.texel_rays=
"jittered"``, the default; along the surfel's direction there is none) and the paths each ray traces.
Its relative noise is r = √(V / M), with V the texel variance between seeds (mean over the texels and RGB
of the active probes) and M the mean squared radiance of the noise-free maps. A glossy ray reads one texel
(or a filter of a few), so r bounds the relative noise a glossy read hands to the probe image; it is the
cheapest figure that stands for the "fixed placement's seed-to-seed spread" of issue 33 without
evaluating a placement several times.

**The pilot: three bakes of the radiance maps only** (no geometry rays, no inside test, no filtering) at
``BakeConfig.pilot_spp`` paths per ray: A and B with the same jitter and independent paths, C with its own
jitter and paths. The texel variance is V(s) = J + P / s: the jitter part J does not fall with the paths
(every path of a ray follows the ray), the path part P / s does. Then

* mean((A − B)²) / 2 estimates P / p (the jitter cancels: same rays),
* mean((A − C)²) / 2 estimates J + P / p (both draws independent), so J is the difference (≥ 0); with
  ``texel_rays="surfel"`` the rays do not depend on the key, so B is already such a map: C is B (no
  third bake) and J comes out exactly 0,
* mean(A · C) estimates M without bias (A and C are independent, so E[A·C] = E[A]·E[C] per texel; the
  mean of A² would add the noise V to it).

Two bakes, as a plain seed-to-seed difference, would see J + P / p and scale all of it as 1 / s: on the
Cornell box (8 probes, 16² maps) and ``n_sub`` = 2, J alone is a relative noise of 12 % (measured: V
5.3e-4 at 1 path, 9.7e-5 at 32), so a count chosen that way for 5 % would have landed at 13 %.

**The choice** (:func:`choose_bake_spp`): the smallest power of two s (``_core.smallest_count``, from 1,
at most ``BakeConfig.max_spp``) with J⁺ + P⁺·p/s ≤ target² · M, where J⁺ and P⁺ are the noise figures at
their one-sided 95 % upper bounds (mean + 1.645 standard errors over the texels, as the evaluation's pilot
takes its floor: ``evaluate._samples``): the texels' squared differences are skewed, and the point
estimate of a few paths tends to fall short. When J⁺ alone exceeds target² · M no
count reaches the target: s is then the smallest count whose path part meets it (P⁺·p/s ≤ target² · M:
more paths could not lower the jitter's share), and a warning says to raise ``n_sub`` (stratified jitter
falls faster than 1 / n_sub²: 12 % at n_sub = 2, 2.9 % at 4 on that Cornell case). The pilot costs
3 · p / s of the bake's path tracing (2 · p / s with surfel rays); the bake itself then runs with the
run's key, exactly as a bake with the fixed count s would.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time

import jax
import jax.numpy as jnp
import numpy as np

from .._core import (
    PILOT_Z,
    ConfigError,
    ProbeSet,
    Scene,
    check_count,
    check_memory,
    is_auto,
    json_number,
    mean_and_se,
    smallest_count,
)
from ._bake import (
    BakeConfig,
    PathTracedRadiance,
    RadianceFn,
    batch_ray_bytes,
    map_resolutions,
    texel_radiance,
)

log = logging.getLogger(__name__)

#: Folded into the bake's key for the pilot, so that the pilot's draws are not the bake's.
_PILOT_STREAM = 0x5A3C


@dataclasses.dataclass(frozen=True)
class BakeSamples:
    """The bake's paths per texel ray and how they were chosen (``metrics.json``'s ``bake_samples``).

    Attributes:
        spp: paths per texel ray the bake runs with.
        chosen_by: ``"fixed"`` (given) or ``"target"`` (from the pilot).
        noise_target: the relative noise aimed at.
        pilot_spp, max_spp: the pilot's count and the cap (``None`` when fixed).
        path_variance: P / p, the texel variance from the paths at the pilot count (falls as 1 / spp).
        path_variance_se: its standard error over the texels.
        jitter_variance: J, the texel variance from the sub-texel jitter (does not fall with spp).
        jitter_variance_se: its standard error over the texels.
        mean_sq_radiance: M, the mean squared radiance of the maps.
        pilot_relative_noise: √((J + P/p) / M), the relative noise at the pilot count.
        predicted_relative_noise: √((J⁺ + P⁺·p/s) / M) at the chosen count, J and P at their upper bounds
            (module docstring).
        jitter_relative_noise: √(J⁺ / M), the part no count can lower.
        target_met: the prediction meets the target (``None`` when fixed).
        seconds: the pilot's wall time.
    """

    spp: int
    chosen_by: str
    noise_target: float
    pilot_spp: int | None = None
    max_spp: int | None = None
    path_variance: float | None = None
    path_variance_se: float | None = None
    jitter_variance: float | None = None
    jitter_variance_se: float | None = None
    mean_sq_radiance: float | None = None
    pilot_relative_noise: float | None = None
    predicted_relative_noise: float | None = None
    jitter_relative_noise: float | None = None
    target_met: bool | None = None
    seconds: float = 0.0

    def radiance_fn(self, radiance_fn: RadianceFn) -> RadianceFn:
        """The bake's radiance at this count: ``radiance_fn`` when the count was given, else the path
        tracer at the chosen count (what :func:`choose_bake_spp` asks its callers to bake with)."""
        return radiance_fn if self.chosen_by == "fixed" else dataclasses.replace(radiance_fn, spp=self.spp)

    def to_dict(self) -> dict:
        """The fields as JSON values (an infinite prediction, of maps without signal, as None)."""
        return {k: json_number(v) for k, v in dataclasses.asdict(self).items()}


def predicted_relative_noise(
    path_variance: float, jitter_variance: float, mean_sq: float, pilot_spp: int, spp: int
):
    """√((J + P·p/s) / M): the maps' relative noise at ``spp`` paths per ray, from the pilot's figures
    (module docstring); ``inf`` when M ≤ 0 and there is noise, 0 without noise."""
    v = jitter_variance + path_variance * pilot_spp / spp
    if mean_sq <= 0:
        return 0.0 if v <= 0 else math.inf
    return math.sqrt(v / mean_sq)


def _pilot_maps(
    pos: np.ndarray, radiance_fn, res: int, geo_res: int, config: BakeConfig, key
) -> tuple[np.ndarray, ...]:
    """The radiance maps A, B (same jitter, other paths) and C (other jitter and paths) of the probes at
    ``pos``, batch by batch as the bake runs them. Surfel rays do not depend on the key, so B already is a
    map with other rays' draw and other paths: C is B, not a third bake (module docstring)."""
    bsz = config.probes_per_batch
    parts = []
    for i, start in enumerate(range(0, len(pos), bsz)):
        k = jax.random.split(jax.random.fold_in(key, i), 5)
        p = jnp.asarray(pos[start : start + bsz])
        radiance = lambda k_dir, k_rad, p=p: texel_radiance(
            p, radiance_fn, res, geo_res, config, k_dir, k_rad
        )[0]
        a, b = radiance(k[0], k[1]), radiance(k[0], k[2])
        c = b if config.texel_rays == "surfel" else radiance(k[3], k[4])
        parts.append([np.asarray(m, np.float64) for m in (a, b, c)])
    return tuple(np.concatenate(x) for x in zip(*parts, strict=True))


def choose_bake_spp(
    scene: Scene,
    probes: ProbeSet,
    *,
    radiance_fn: RadianceFn,
    key: jax.Array,
    config: BakeConfig,
    spp: int | str,
) -> BakeSamples:
    """The paths per texel ray of a bake: ``spp`` when it is an int, else chosen from
    ``config.noise_target`` by a pilot (module docstring). Bake then with ``result.radiance_fn(radiance_fn)``
    and the same ``key``.

    Args:
        scene: the scene.
        probes: the probe set to bake (the pilot bakes its active probes).
        radiance_fn: the bake's radiance; with ``"auto"`` the path tracer (:func:`path_traced_radiance`),
            which the pilot runs at ``config.pilot_spp`` paths.
        key: the bake's key (the pilot draws from a stream folded from it, not from the bake's).
        config: the bake's settings: resolution, ``n_sub``, batch size, ``noise_target``, ``pilot_spp``,
            ``max_spp``.
        spp: an int (fixed) or ``"auto"``.

    Returns:
        :class:`BakeSamples`.

    Raises:
        ConfigError: ``spp`` neither a positive int nor ``"auto"``; ``"auto"`` with a radiance function
            that is not the path tracer (its count cannot be changed) or a set without active probes.
        ResourceError: a pilot batch and its maps would not fit in memory.
    """
    check_count(spp, "bake spp")
    if not is_auto(spp):
        return BakeSamples(spp=int(spp), chosen_by="fixed", noise_target=config.noise_target)
    if not isinstance(radiance_fn, PathTracedRadiance):
        raise ConfigError("bake spp 'auto' needs the path tracer's radiance (probes.path_traced_radiance)")
    pos = np.asarray(probes.pos_world, np.float32)[np.asarray(probes.active)]
    if len(pos) == 0:
        raise ConfigError("bake spp 'auto': the probe set has no active probe to measure the noise on")
    res, geo_res = map_resolutions(scene, config)
    p = config.pilot_spp
    batch = min(config.probes_per_batch, len(pos))
    check_memory(
        batch_ray_bytes(batch, res, config.n_sub) + 3 * len(pos) * res * res * 3 * 8,
        f"bake pilot of {len(pos)} probes at radiance_res={res}, n_sub={config.n_sub}",
        "lower radiance_res, n_sub or probes_per_batch",
    )
    t0 = time.perf_counter()
    a, b, c = _pilot_maps(
        pos,
        dataclasses.replace(radiance_fn, spp=p),
        res,
        geo_res,
        config,
        jax.random.fold_in(key, _PILOT_STREAM),
    )
    # per texel (mean over RGB): the paths' and the jitter's squared differences (module docstring)
    d_path = np.mean((a - b) ** 2 / 2, axis=-1).reshape(-1)
    d_jitter = np.mean((a - c) ** 2 / 2, axis=-1).reshape(-1) - d_path  # exactly 0 where C is B
    (path_var, path_se), (jitter_var, jitter_se) = mean_and_se(d_path), mean_and_se(d_jitter)
    path_up, jitter_up = path_var + PILOT_Z * path_se, max(jitter_var + PILOT_Z * jitter_se, 0.0)
    mean_sq = float(np.mean(a * c))
    seconds = time.perf_counter() - t0
    t, cap = float(config.noise_target), config.max_spp
    rel = lambda s: predicted_relative_noise(path_up, jitter_up, mean_sq, p, s)
    jitter_rel = predicted_relative_noise(0.0, jitter_up, mean_sq, p, 1)
    if jitter_rel <= t:
        chosen, met = smallest_count(lambda s: rel(s) <= t, lo=1, cap=cap)
    else:  # no count reaches it: the paths' share alone meets it (module docstring)
        chosen, _ = smallest_count(
            lambda s: predicted_relative_noise(path_up, 0.0, mean_sq, p, s) <= t, lo=1, cap=cap
        )
        met = False
    out = BakeSamples(
        spp=chosen,
        chosen_by="target",
        noise_target=t,
        pilot_spp=p,
        max_spp=cap,
        path_variance=path_var,
        path_variance_se=path_se,
        jitter_variance=max(jitter_var, 0.0),
        jitter_variance_se=jitter_se,
        mean_sq_radiance=mean_sq,
        pilot_relative_noise=predicted_relative_noise(path_var, max(jitter_var, 0.0), mean_sq, p, p),
        predicted_relative_noise=rel(chosen),
        jitter_relative_noise=jitter_rel,
        target_met=met,
        seconds=seconds,
    )
    _say(out)
    return out


def _say(s: BakeSamples) -> None:
    """Log the choice: info when the target is met, else a warning naming the way out."""
    text = (
        f"bake spp auto: pilot at {s.pilot_spp} paths per ray: relative noise {s.pilot_relative_noise:.3g} "
        f"(sub-texel jitter {s.jitter_relative_noise:.3g}); {s.spp} paths per ray predict "
        f"{s.predicted_relative_noise:.3g} for a target of {s.noise_target:g}"
    )
    if s.target_met:
        log.info("%s", text)
    elif s.jitter_relative_noise is not None and s.jitter_relative_noise > s.noise_target:
        log.warning("%s: the sub-texel jitter alone exceeds the target, raise n_sub", text)
    else:
        log.warning("%s: max_spp=%d cannot reach the target, raise max_spp", text, s.max_spp)
