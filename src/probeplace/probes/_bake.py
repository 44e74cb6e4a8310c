"""Bake light-field probes (McGuire et al. 2017 §3) for any :class:`~probeplace._core.ProbeSet`.

Per probe and interior texel of the radiance map (octahedral, Cigolle 2014; ``_core._octahedral``):

* the **geometry** maps — radial distance and shading normal — come from the ray through the texel
  *centre*, so each texel is one surfel (McGuire §4: "each octahedral texel describes a planar patch");
* the **radiance** maps average ``n_sub``² rays with stratified sub-texel jitter, each path traced by
  the reference renderer (issue 3: "radiance from path tracing along each texel's direction"). What the
  renderer calls ``direct + diffuse_indirect + glossy_indirect`` for a camera at the probe is the light
  *reflected* toward the probe (stored in ``radiance``); its ``emission`` (emitters and sky seen
  directly) is stored apart (DESIGN.md "indirect means reflected").

A probe is flagged ``inside`` when more than ``inside_backface_share`` of its texel-centre rays first
hit a back face: from inside a closed solid almost every ray does, from free space only rays that meet a
one-sided sheet from behind do.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float
from tqdm.auto import tqdm

from .._core import (
    ConfigError,
    LightFieldProbes,
    ProbeSet,
    Scene,
    SceneError,
    add_border,
    jittered_texel_directions,
    texel_directions,
)
from .._core._errors import check_memory
from ._filter import distance_moments, irradiance_map, mip_chains

log = logging.getLogger(__name__)

#: ``radiance_fn(origins, directions, key) -> (reflected, emitted)``, both (n, 3): radiance arriving at
#: each origin along -direction, split as in the module docstring.
RadianceFn = Callable[[Float[Array, "n 3"], Float[Array, "n 3"], jax.Array], tuple[Array, Array]]


def path_traced_radiance(
    scene: Scene,
    *,
    spp: int = 16,
    max_depth: int = 8,
    specular: float = 1.0,
    caster=None,
) -> RadianceFn:
    """The reference path tracer as a :data:`RadianceFn`: ``render.trace_rays`` split into reflected
    (direct + diffuse indirect + glossy indirect) and emitted (emission, sky) radiance.

    ``spp`` paths per ray; with ``n_sub``² jittered rays per texel a texel averages ``spp·n_sub²`` paths.
    Each call uses a fresh random stream from its key, so batches are independent.

    Raises:
        SceneError: the scene has no light (every baked map would be black).
    """
    from ..render import trace_rays

    if not scene.has_light:
        raise SceneError(
            f"scene {scene.name!r} has no light (no emissive material, sun or sky): path-traced probe "
            "radiance would be all black; add a light"
        )

    def fn(origins, directions, key):
        r = trace_rays(
            scene,
            origins,
            directions,
            spp=spp,
            key=key,
            max_depth=max_depth,
            specular=specular,
            caster=caster,
        )
        emitted = r.component("emission")
        return r.component("full") - emitted, emitted

    return fn


def _is_pow2(n: int) -> bool:
    return n >= 1 and (n & (n - 1)) == 0


@dataclasses.dataclass(frozen=True, kw_only=True)
class BakeConfig:
    """Bake settings.

    Attributes:
        radiance_res: interior resolution of the radiance / emission / normal / distance maps (a power
            of two, for the MIP chains); ``None`` derives it with :func:`default_radiance_res`.
        irradiance_res: interior resolution of the irradiance map (McGuire §3: low frequency, 8 is
            DDGI's choice).
        moments_res: interior resolution of the distance-moment map (DDGI uses 16).
        n_sub: ``n_sub``² jittered rays per radiance texel.
        moment_power: exponent p of the cosine-power lobe for the moments (McGuire §5.2 gives no value;
            DDGI's reference implementation filters distance with a sharp lobe, we default to 50).
        inside_backface_share: a probe whose share of back-face first hits exceeds this is ``inside``.
        probes_per_batch: probes traced at once (memory ≈ probes × res² × n_sub² × 200 bytes).
        quality: scales the derived radiance resolution.
        progress: show a progress bar.
    """

    radiance_res: int | None = None
    irradiance_res: int = 8
    moments_res: int = 16
    n_sub: int = 2
    moment_power: float = 50.0
    inside_backface_share: float = 0.5
    probes_per_batch: int = 8
    quality: float = 1.0
    progress: bool = True

    def __post_init__(self):
        if self.radiance_res is not None and not (_is_pow2(self.radiance_res) and self.radiance_res >= 2):
            raise ConfigError(
                f"BakeConfig.radiance_res must be a power of two ≥ 2, got {self.radiance_res!r}"
            )
        for name in ("irradiance_res", "moments_res", "n_sub", "probes_per_batch"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ConfigError(f"BakeConfig.{name} must be a positive int, got {v!r}")
        if not (self.moment_power > 0 and math.isfinite(self.moment_power)):
            raise ConfigError(f"BakeConfig.moment_power must be positive, got {self.moment_power!r}")
        if not 0.0 < self.inside_backface_share < 1.0:
            raise ConfigError(
                f"BakeConfig.inside_backface_share must be in (0, 1), got {self.inside_backface_share!r}"
            )
        if not self.quality > 0:
            raise ConfigError(f"BakeConfig.quality must be positive, got {self.quality!r}")


def default_radiance_res(scene: Scene, *, quality: float = 1.0) -> int:
    """Radiance-map resolution so that a texel's footprint at the typical probe-to-wall distance is about
    one surface-sample spacing (the scene's own feature scale), rounded to a power of two in [16, 128].

    A texel subtends ≈ √(4π)/R rad; at distance d its footprint is ≈ 3.5 d / R. The typical distance is
    taken as a quarter of the bounding-box diagonal, the spacing from ``geometry.default_sample_spacing``.
    McGuire §3 found no gain above 128² and good results from 32².
    """
    from ..geometry import default_sample_spacing

    lo, hi = (np.asarray(b) for b in scene.bounds)
    d = 0.25 * float(np.linalg.norm(hi - lo))
    spacing = default_sample_spacing(scene, quality=quality)
    r = 3.5 * d / spacing
    return int(2 ** np.clip(np.round(np.log2(max(r, 1.0))), 4, 7))


def _warn_probe_layout(pos: np.ndarray, lo: np.ndarray, hi: np.ndarray, what: str) -> None:
    """Log (not refuse) duplicate probes and probes outside the scene box: both are legal but usually a
    mistake — duplicates cost work for no gain, outside probes see the scene from beyond its bounds."""
    n_dup = len(pos) - len(np.unique(pos, axis=0))
    if n_dup:
        log.warning("%s: %d of %d probe positions are duplicates", what, n_dup, len(pos))
    out = ((pos < lo) | (pos > hi)).any(axis=1)
    if out.any():
        log.warning(
            "%s: %d of %d probes lie outside the scene bounds %s–%s", what, out.sum(), len(pos), lo, hi
        )


def _bake_batch(
    pos: Float[Array, "b 3"],
    caster,
    radiance_fn: RadianceFn,
    res: int,
    n_sub: int,
    far: float,
    key: jax.Array,
):
    b = pos.shape[0]
    centre_dirs = jnp.broadcast_to(texel_directions(res), (b, res, res, 3)).reshape(-1, 3)
    origins = jnp.repeat(pos, res * res, axis=0)
    hit = caster.closest_hit(origins, centre_dirs)
    is_hit = np.asarray(hit.tri) >= 0
    t = np.asarray(hit.t)
    distance = np.where(is_hit, t, far).reshape(b, res, res)
    normal = np.where(is_hit[:, None], np.asarray(hit.shading_normal), 0.0).reshape(b, res, res, 3)
    facing = np.sum(np.asarray(hit.geo_normal) * np.asarray(centre_dirs), axis=-1)
    backface = (is_hit & (facing > 0)).reshape(b, res * res).mean(axis=1)

    k_dir, k_rad = jax.random.split(key)
    sub = n_sub * n_sub
    dirs = jax.vmap(lambda k: jittered_texel_directions(res, n_sub, key=k))(jax.random.split(k_dir, b))
    dirs = dirs.reshape(-1, 3)
    sub_origins = jnp.repeat(pos, res * res * sub, axis=0)
    reflected, emitted = radiance_fn(sub_origins, dirs, k_rad)
    radiance = np.asarray(reflected).reshape(b, res, res, sub, 3).mean(axis=3)
    emission = np.asarray(emitted).reshape(b, res, res, sub, 3).mean(axis=3)
    return radiance, emission, normal, distance, backface


def bake_probes(
    scene: Scene,
    probes: ProbeSet,
    *,
    caster,
    radiance_fn: RadianceFn,
    key: jax.Array,
    config: BakeConfig = BakeConfig(),
) -> LightFieldProbes:
    """Bake every probe of ``probes`` (inactive rows too, so shapes stay fixed; they are masked later).

    Args:
        scene: the scene (for the far distance and the derived resolution).
        probes: probe positions, world frame.
        caster: an exact ray caster (``geometry.make_caster``) for the texel-centre geometry rays.
        radiance_fn: path-traced radiance along rays, split into (reflected, emitted); see
            :data:`RadianceFn` and ``render.probe_radiance_fn``.
        key: PRNG key for jitter and path sampling.
        config: resolutions and filters.

    Returns:
        The baked :class:`LightFieldProbes`; float32, maps with one-texel borders.

    Raises:
        ConfigError: bad probe positions (NaN/inf), empty set or configuration.
        ResourceError: one batch plus the output maps would not fit in memory (checked before allocating).

    Duplicate probes and probes outside the scene bounds are baked as given, with a logged warning.
    """
    pos = np.asarray(probes.pos_world, np.float32)
    if not np.isfinite(pos).all():
        raise ConfigError(f"probe positions must be finite; {int((~np.isfinite(pos)).any(-1).sum())} are not")
    if pos.shape[0] == 0:
        raise ConfigError("cannot bake an empty probe set")
    res = config.radiance_res or default_radiance_res(scene, quality=config.quality)
    lo, hi = (np.asarray(b) for b in scene.bounds)
    far = float(2.0 * np.linalg.norm(hi - lo))

    n = pos.shape[0]
    bsz = config.probes_per_batch
    # Refuse up front (issue 9): one batch's rays (~200 bytes per path, see BakeConfig) plus the output
    # maps (radiance, emission, normal 3 floats, distance 1, kept as NumPy and as JAX copies).
    need = min(bsz, n) * res * res * config.n_sub**2 * 200 + n * (res + 2) ** 2 * 10 * 4 * 2
    check_memory(
        need,
        f"bake of {n} probes at radiance_res={res}, n_sub={config.n_sub}, probes_per_batch={bsz}",
        "lower radiance_res, n_sub or probes_per_batch",
    )
    _warn_probe_layout(pos[np.asarray(probes.active)], lo, hi, "bake")  # inactive rows are padding
    parts: list[tuple] = []
    keys = jax.random.split(key, (n + bsz - 1) // bsz)
    bar = tqdm(total=n, desc=f"bake {res}² probes", unit="probe", disable=not config.progress)
    for i, start in enumerate(range(0, n, bsz)):
        parts.append(
            _bake_batch(
                jnp.asarray(pos[start : start + bsz]), caster, radiance_fn, res, config.n_sub, far, keys[i]
            )
        )
        bar.update(min(bsz, n - start))
    bar.close()
    radiance, emission, normal, distance, backface = (np.concatenate(x) for x in zip(*parts, strict=True))
    inside = backface > config.inside_backface_share
    if inside.any():
        log.warning("%d of %d probes are inside geometry (most first hits are back faces)", inside.sum(), n)

    f32 = lambda x: jnp.asarray(x, jnp.float32)
    irr = irradiance_map(f32(radiance), config.irradiance_res)
    mom = distance_moments(f32(distance), config.moments_res, config.moment_power)
    mins, maxs = mip_chains(f32(distance))
    return LightFieldProbes(
        pos_world=f32(pos),
        active=jnp.asarray(probes.active),
        inside=jnp.asarray(inside),
        radiance=add_border(f32(radiance)),
        emission=add_border(f32(emission)),
        normal=add_border(f32(normal)),
        distance=add_border(f32(distance)[..., None])[..., 0],
        irradiance=add_border(irr),
        moments=add_border(mom),
        distance_min_mips=mins,
        distance_max_mips=maxs,
        far=jnp.float32(far),
    )
