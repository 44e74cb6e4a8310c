"""The reference path tracer's driver: batches of pixel samples, progressive accumulation, variance.

Work is cut into batches of ``paths_per_batch`` paths (a tile of pixels × a group of sample indices);
each batch runs the wavefront bounce loop of :mod:`._integrator` and returns, per pixel and component,
the batch mean and the sum of squared deviations, which the host merges into running per-pixel
statistics (Chan, Golub & LeVeque 1979 pairwise update, in float64 so a million samples lose nothing).
The variance of the pixel mean is M2 / (n (n − 1)).

With a jittable caster (the JAX brute-force or BVH casters) a whole batch — every bounce — is one
jitted function with a ``lax.while_loop`` that stops when all paths are dead; a host caster (Embree)
gets a Python bounce loop whose shading steps are jitted.
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int, Key, UInt32

from .._core import Camera, ConfigError, Scene, SceneError, check_memory, next_pow2
from .._core.runtime import progress_bar
from ..geometry import AbstractRayCaster, make_caster
from ._backends import BACKEND_CHOICES as BACKEND_CHOICES
from ._backends import BACKENDS as BACKENDS
from ._camera import camera_rays
from ._integrator import COMPONENTS, Paths, ShadeContext, add_shadowed, components, init_paths, shade
from ._lights import light_table
from ._sampling import DIM_DIR_U, path_uniforms, seed_from_key

log = logging.getLogger(__name__)

SCHEDULES = ("compact", "fused")


@functools.cache
def _auto_backend() -> str:
    if jax.default_backend() != "cpu":  # on a GPU the JAX path tracer is the fast one
        return "jax"
    from ._mitsuba_backend import load_mitsuba

    try:
        load_mitsuba()
    except ImportError as e:
        log.info("backend auto: Mitsuba's LLVM variant cannot load, using jax (%s)", e)
        return "jax"
    return "mitsuba"


def resolve_backend(backend: str, who: str = "backend") -> str:
    """The path tracer that runs for a configured ``backend`` (one of :data:`BACKEND_CHOICES`).

    ``"auto"`` is ``"jax"`` when JAX's default device is an accelerator, else ``"mitsuba"`` where Mitsuba 3's
    LLVM variant loads (4–9× the JAX path tracer's samples/s on a CPU, benchmarks/pathtrace.py), else
    ``"jax"``; the two agree within noise (tests/render/test_mitsuba_backend.py), so ``auto`` changes speed,
    not the estimate's expectation. Settings records (``BakeSettings.backend``, ``metrics["backend"]``) hold
    the resolved name.

    Raises:
        ConfigError: ``backend`` is not one of :data:`BACKEND_CHOICES` (``who`` names the setting).
    """
    if backend not in BACKEND_CHOICES:
        raise ConfigError(f"{who} must be one of {BACKEND_CHOICES}, got {backend!r}")
    return _auto_backend() if backend == "auto" else backend


@dataclass(frozen=True, kw_only=True)
class RenderConfig:
    """Settings of a reference render (hashable: it is a static argument of the jitted batch).

    Attributes:
        width, height: image size in pixels.
        spp: samples (paths) per pixel.
        max_depth: longest path in segments, camera ray included (Mitsuba's convention: 1 = emitters
            seen directly, 2 = direct lighting only, …).
        rr_depth: Russian roulette starts at this depth (Mitsuba's default 5).
        specular: dielectric specular factor of every material (KHR_materials_specular; 1 = glTF,
            0 = pure Lambert dielectrics, used to compare with Mitsuba's ``diffuse``).
        paths_per_batch: paths traced at once (memory ~ 200 bytes per path).
        progress: show a tqdm progress bar.
        schedule: bounce loop for jittable casters: ``"compact"`` (host loop that casts and shades only
            the live paths of each bounce, padded to power-of-two sizes) or ``"fused"`` (one jitted
            ``while_loop`` over every lane; see docs/render.md "Performance"). Host casters always get
            the host loop.
        backend: ``"jax"`` (default) or ``"mitsuba"``: the same model, estimator and random numbers
            compiled by Mitsuba 3 / Dr.Jit with Embree ray casts (``_mitsuba_backend``; CPU only, several
            times faster there; docs/render.md "Backends"). ``schedule`` and a ``caster`` are JAX-only.
            ``"auto"`` is replaced by the backend :func:`resolve_backend` picks.
    """

    width: int
    height: int
    spp: int
    max_depth: int = 8
    rr_depth: int = 5
    specular: float = 1.0
    paths_per_batch: int = 1 << 18
    progress: bool = True
    schedule: str = "compact"
    backend: str = "jax"

    def __post_init__(self):
        for name in ("width", "height", "spp", "max_depth", "rr_depth", "paths_per_batch"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ConfigError(f"RenderConfig.{name} must be a positive int, got {v!r}")
        if self.schedule not in SCHEDULES:
            raise ConfigError(f"RenderConfig.schedule must be one of {SCHEDULES}, got {self.schedule!r}")
        if not 0.0 <= float(self.specular) <= 1.0:
            raise ConfigError(f"RenderConfig.specular must be in [0, 1], got {self.specular!r}")
        object.__setattr__(self, "backend", resolve_backend(self.backend, "RenderConfig.backend"))


class RenderResult(eqx.Module):
    """Per-pixel estimates of each component (see :data:`COMPONENTS` and docs/render.md).

    Attributes:
        mean: pixel means, (component, row, column, RGB); row 0 is the image top.
        var_of_mean: estimated variance of each pixel mean (sample variance / spp).
        spp: samples per pixel.
        components: component names, in the order of the first axis.
    """

    mean: Float[Array, "n_comp h w 3"]
    var_of_mean: Float[Array, "n_comp h w 3"]
    spp: int = eqx.field(static=True)
    components: tuple[str, ...] = eqx.field(static=True, default=COMPONENTS)

    def image(self, component: str = "full") -> Float[Array, "h w 3"]:
        """The mean image of one component."""
        return self.mean[self._index(component)]

    def variance(self, component: str = "full") -> Float[Array, "h w 3"]:
        """The variance-of-the-mean image of one component."""
        return self.var_of_mean[self._index(component)]

    def _index(self, component: str) -> int:
        if component not in self.components:
            raise KeyError(f"no component {component!r}; components: {self.components}")
        return self.components.index(component)


def _batch_layout(cfg: RenderConfig, n_items: int) -> tuple[int, int]:
    """(items per batch P, samples per batch G) with P·G ≤ paths_per_batch; P is rounded up to a power
    of two (at least 64) so renders of different sizes share compiled kernels."""
    budget = cfg.paths_per_batch
    p = next_pow2(n_items, lo=64, hi=budget)
    g = max(1, min(cfg.spp, budget // p))
    return p, g


class _CameraSource(eqx.Module):
    """Camera rays: item i is pixel i (row-major), jittered by the bounce-0 uniforms (box filter).

    Width and height are array leaves so a new image size does not recompile the batch kernel."""

    camera: Camera
    width: Int[Array, ""]
    height: Int[Array, ""]

    def rays(self, item: Int[Array, " n"], local: Int[Array, " n"], u: Float[Array, "n 2"]):
        del local
        return camera_rays(self.camera, self.width, self.height, item, u)


class _RayBatch(eqx.Module):
    """Given rays of one batch (rows = batch-local items, padded); the same ray for every sample."""

    origins: Float[Array, "p 3"]
    directions: Float[Array, "p 3"]

    def rays(self, item: Int[Array, " n"], local: Int[Array, " n"], u: Float[Array, "n 2"]):
        del item
        return self.origins[local], self.directions[local]


def _start(
    source, seed, offset, pix0, smp0, spp, n_items, p: int, g: int
) -> tuple[Paths, Bool[Array, "p g"]]:
    """Paths for items pix0 … pix0+p−1 × samples smp0 … smp0+g−1 (item-major lanes).

    The random-number stream of item i is ``offset + i`` (a caller tracing rays in chunks passes the
    chunk's first index so chunks never share streams).
    """
    local = jnp.arange(p, dtype=jnp.int32)
    pix = pix0 + local
    smp = smp0 + jnp.arange(g, dtype=jnp.int32)
    valid = (pix[:, None] < n_items) & (smp[None, :] < spp)
    pix_l = jnp.repeat(jnp.minimum(pix, n_items - 1), g)
    loc_l = jnp.repeat(local, g)
    smp_l = jnp.tile(smp, p)
    stream = pix_l + offset
    u = jax.vmap(path_uniforms, in_axes=(None, 0, 0, None))(seed, stream, smp_l, 0)
    o, d = source.rays(pix_l, loc_l, u[:, DIM_DIR_U : DIM_DIR_U + 2])
    return init_paths(o, d, stream, smp_l, valid.reshape(-1)), valid


def _reduce(paths: Paths, valid: Bool[Array, "p g"]):
    """Per-item batch mean and sum of squared deviations of every component (p, len(COMPONENTS), 3), and
    counts (p,)."""
    p, g = valid.shape
    c = components(paths).reshape(p, g, len(COMPONENTS), 3)
    w = valid.astype(c.dtype)[:, :, None, None]
    cnt = jnp.sum(valid, axis=1).astype(c.dtype)
    safe = jnp.maximum(cnt, 1.0)[:, None, None]
    mean = jnp.sum(c * w, axis=1) / safe
    m2 = jnp.sum(w * (c - mean[:, None]) ** 2, axis=1)
    return mean, m2, cnt


@eqx.filter_jit
def _batch_jit(ctx: ShadeContext, caster, source, seed, offset, pix0, smp0, spp, n_items, p: int, g: int):
    """One batch, every bounce, as one jitted function (jittable casters). Only (p, g) and the caster's
    and source's types/shapes are static, so depth, spp, image size and seed changes never recompile."""
    paths, valid = _start(source, seed, offset, pix0, smp0, spp, n_items, p, g)

    def cond(carry):
        k, paths = carry
        return (k < ctx.max_depth) & jnp.any(paths.alive)

    def body(carry):
        k, paths = carry
        hit = caster.closest_hit(paths.origin, paths.direction)
        paths, shadow = shade(ctx, seed, k, paths, hit)
        occ = caster.occluded(shadow.origin, shadow.direction, shadow.t_max)
        return k + 1, add_shadowed(paths, occ, k)

    _, paths = jax.lax.while_loop(cond, body, (jnp.asarray(1, jnp.int32), paths))
    # Last segment (k = max_depth): only the emission at x_k, no shadow ray to cast.
    hit = caster.closest_hit(paths.origin, paths.direction)
    paths, _ = shade(ctx, seed, ctx.max_depth, paths, hit)
    return _reduce(paths, valid)


_start_jit = eqx.filter_jit(_start)
_shade_jit = eqx.filter_jit(shade)
_add_shadowed_jit = eqx.filter_jit(add_shadowed)
_reduce_jit = eqx.filter_jit(_reduce)


@eqx.filter_jit
def _scatter_hit(hit, live: Int[Array, " m"], n: int):
    """A full-batch Hit from the hits of the live lanes (dead lanes: zeros; shading ignores them)."""
    return jax.tree.map(lambda a: jnp.zeros((n, *a.shape[1:]), a.dtype).at[live].set(a), hit)


def _batch_host(ctx, caster, source, seed, offset, pix0, smp0, spp, n_items, p, g):
    """One batch with a host bounce loop (host casters such as Embree); shading stays jitted.

    Only live paths are cast (closest hit), and only shadow rays with t_max > 0 (those that carry a
    light sample): dead lanes cost the host caster nothing. Live index lists are padded to power-of-two
    lengths so the scatter compiles a few times per render, not once per bounce."""
    paths, valid = _start_jit(source, seed, offset, pix0, smp0, spp, n_items, p, g)
    n = p * g
    max_depth = int(ctx.max_depth)
    for k in range(1, max_depth + 1):
        alive = np.asarray(paths.alive)
        live = np.flatnonzero(alive)
        if len(live) == 0:
            break
        m = next_pow2(len(live), hi=n)
        live_p = np.concatenate([live, np.full(m - len(live), live[0])]).astype(np.int32)  # repeats: same hit
        origin, direction = np.asarray(paths.origin), np.asarray(paths.direction)
        hit = caster.closest_hit(jnp.asarray(origin[live_p]), jnp.asarray(direction[live_p]))
        hit = _scatter_hit(hit, jnp.asarray(live_p), n)
        kk = jnp.asarray(k, jnp.int32)
        paths, shadow = _shade_jit(ctx, seed, kk, paths, hit)
        if k < max_depth:
            t_max = np.asarray(shadow.t_max)
            cast = np.flatnonzero(t_max > 0)
            occ = np.zeros(n, bool)
            if len(cast):
                so, sd = np.asarray(shadow.origin), np.asarray(shadow.direction)
                occ[cast] = caster.occluded_host(so[cast], sd[cast], t_max[cast])
            paths = _add_shadowed_jit(paths, jnp.asarray(occ), kk)
    return _reduce_jit(paths, valid)


_LANE_BLOCK = 8192  # lanes per block of a compacted bounce: the block's temporaries stay in cache


@eqx.filter_jit
def _batch_compact(ctx: ShadeContext, caster, source, seed, offset, pix0, smp0, spp, n_items, p: int, g: int):
    """One batch as one jitted function with live-lane compaction (jittable casters).

    Per bounce, the indices of the live paths are packed to the front (``jnp.nonzero`` with a static
    size) and only ⌈live / B⌉ blocks of B = :data:`_LANE_BLOCK` lanes are cast and shaded (a
    ``fori_loop`` with a traced trip count), each block gathered from and scattered back into the full
    path state. A path that escaped or lost at Russian roulette costs nothing afterwards, and XLA:CPU's
    many per-op loops of the vmapped shading run over one block's temporaries, which stay in cache (see
    docs/render.md "Performance"). Same random numbers per (pixel, sample, bounce) as :func:`_batch_jit`,
    so the same image up to float round-off; one compilation per (p, g) as well."""
    paths, valid = _start(source, seed, offset, pix0, smp0, spp, n_items, p, g)
    n = p * g
    b = min(_LANE_BLOCK, n)
    n_pad = -(-n // b) * b

    def bounce(carry):
        k, paths = carry
        idx = jnp.nonzero(paths.alive, size=n_pad, fill_value=n)[0].astype(jnp.int32)
        n_blocks = (jnp.sum(paths.alive, dtype=jnp.int32) + (b - 1)) // b

        def block(i, paths):
            ids = jax.lax.dynamic_slice(idx, (i * b,), (b,))
            sub = jax.tree.map(lambda a: a.at[ids].get(mode="fill", fill_value=0), paths)
            hit = caster.closest_hit(sub.origin, sub.direction)
            sub, shadow = shade(ctx, seed, k, sub, hit)
            # at k = max_depth shade draws no light sample (NEE is zero): shadow rays have t_max = 0
            occ = caster.occluded(shadow.origin, shadow.direction, shadow.t_max)
            sub = add_shadowed(sub, occ, k)
            return jax.tree.map(lambda a, v: a.at[ids].set(v, mode="drop"), paths, sub)

        return k + 1, jax.lax.fori_loop(0, n_blocks, block, paths)

    def cond(carry):
        k, paths = carry
        return (k <= ctx.max_depth) & jnp.any(paths.alive)

    _, paths = jax.lax.while_loop(cond, bounce, (jnp.asarray(1, jnp.int32), paths))
    return _reduce(paths, valid)


def shade_context(scene: Scene, cfg: RenderConfig) -> ShadeContext:
    """The fixed shading inputs of a render (materials, light tables, sky, settings)."""
    return ShadeContext(
        materials=scene.materials,
        lights=light_table(scene),
        sky=scene.sky_radiance.astype(jnp.float32),
        specular=jnp.asarray(cfg.specular, jnp.float32),
        max_depth=jnp.asarray(cfg.max_depth, jnp.int32),
        rr_depth=jnp.asarray(cfg.rr_depth, jnp.int32),
    )


def default_caster(scene: Scene) -> AbstractRayCaster:
    """The caster :func:`render` uses when given none: ``geometry.make_caster(scene, use="render")``
    (brute force for tiny scenes, so the whole bounce loop runs in one jitted function; else Embree on
    the host when embreex is installed, else the JAX BVH)."""
    return make_caster(scene, use="render")


def _seed(key) -> UInt32[Array, ""]:
    k = jnp.asarray(key)
    if jnp.issubdtype(k.dtype, jax.dtypes.prng_key):
        return seed_from_key(k)
    if k.shape != () or not jnp.issubdtype(k.dtype, jnp.integer):
        raise TypeError(f"key must be a JAX PRNG key or an integer seed, got {k.dtype}{k.shape}")
    return k.astype(jnp.uint32)


def _accumulate(scene, source, n_items: int, config: RenderConfig, seed, caster, offset: int, unit: str):
    """Trace ``config.spp`` samples of every item of ``source``; float64 (mean, var_of_mean), each
    (n, len(COMPONENTS), 3)."""
    if config.backend == "mitsuba":
        if caster is not None:
            raise ConfigError("a caster is a backend='jax' option; backend='mitsuba' casts rays with Embree")
        from ._mitsuba_backend import batch_runner

        run = batch_runner(
            scene,
            max_depth=config.max_depth,
            rr_depth=config.rr_depth,
            specular=config.specular,
        )
        ctx = None
    else:
        if caster is None:
            caster = default_caster(scene)
        if not isinstance(caster, AbstractRayCaster):
            raise TypeError(f"caster must be an AbstractRayCaster, got {type(caster).__name__}")
        ctx = shade_context(scene, config)
        if not caster.jittable:
            run = _batch_host
        else:
            run = _batch_compact if config.schedule == "compact" else _batch_jit
    p, g = _batch_layout(config, n_items)
    n = np.zeros(n_items)
    mean = np.zeros((n_items, len(COMPONENTS), 3))
    m2 = np.zeros_like(mean)
    # the Mitsuba batches take plain ints (a JAX scalar costs a dispatch per batch there)
    i32 = int if config.backend == "mitsuba" else (lambda x: jnp.asarray(x, jnp.int32))
    bar = progress_bar(total=config.spp * n_items, disable=not config.progress, unit=unit, unit_scale=True)
    for s0 in range(0, config.spp, g):
        for pix0 in range(0, n_items, p):
            src = source(pix0, p) if callable(source) else source
            args = (i32(offset), i32(pix0), i32(s0), i32(config.spp), i32(n_items), p, g)
            b_mean, b_m2, b_cnt = run(ctx, caster, src, seed, *args)
            sl = slice(pix0, min(pix0 + p, n_items))
            k = sl.stop - sl.start
            nb = np.asarray(b_cnt, np.float64)[:k]
            mb = np.asarray(b_mean, np.float64)[:k]
            m2b = np.asarray(b_m2, np.float64)[:k]
            # Chan, Golub & LeVeque (1979) pairwise merge of (count, mean, M2).
            na = n[sl]
            tot = na + nb
            frac = np.where(tot > 0, nb / np.maximum(tot, 1), 0.0)[:, None, None]
            delta = mb - mean[sl]
            mean[sl] += delta * frac
            m2[sl] += m2b + delta**2 * (na * frac[:, 0, 0])[:, None, None]
            n[sl] = tot
            bar.update(int(nb.sum()))
    bar.close()
    var = m2 / np.maximum(n * (n - 1), 1)[:, None, None]
    return mean, var


def _check_renderable(scene: Scene, n_items: int, config: RenderConfig, what: str) -> None:
    """Refuse, up front, a scene without light (every image would be black) and a job whose float64
    running statistics (mean + variance per component) and path batch would not fit in memory."""
    if not scene.has_light:
        raise SceneError(
            f"{what}: scene {scene.name!r} has no light (no emissive material, sun or sky); "
            "every image would be black"
        )
    stats = n_items * len(COMPONENTS) * 3 * 8 * 2
    batch = min(int(config.paths_per_batch), n_items * int(config.spp)) * 200  # ~200 B of path state each
    check_memory(
        stats + batch,
        f"{what} of {n_items} items × {config.spp} spp",
        "use a smaller image or fewer rays per call",
    )


def render(
    scene: Scene,
    view: str | Camera,
    config: RenderConfig,
    *,
    key: Key[Array, ""] | UInt32[Array, ""] | int,
    caster: AbstractRayCaster | None = None,
) -> RenderResult:
    """Path-trace one view of ``scene`` into its components with per-pixel variance estimates.

    Not differentiable (a reference renderer). Progressive: samples are added batch by batch into
    running float64 statistics, with a tqdm progress bar when ``config.progress``.

    Args:
        scene: the scene (radiance units: those of its emission / sun / sky).
        view: a camera or the name of one of ``scene.views``.
        config: image size, spp, depth, batching.
        key: a JAX PRNG key, or an integer seed (as from :func:`seed_from_key`). Pixel sample s of pixel p
            uses the random numbers ``path_uniforms(seed, p, s, bounce)`` whatever the batching.
        caster: any :class:`~probeplace.geometry.AbstractRayCaster` (a jittable one runs each batch as
            one jitted function, a host one such as Embree gets a host bounce loop around jitted
            shading); default :func:`default_caster`.

    Returns:
        A :class:`RenderResult` (float32; ``image("full")`` is the beauty image).

    Raises:
        ConfigError: bad settings (a ``caster`` with ``backend="mitsuba"`` too); KeyError: unknown view
        name; TypeError: bad key or caster; SceneError: the scene has no light; ResourceError: the image
        statistics would not fit in memory; ImportError: ``backend="mitsuba"`` without Mitsuba's LLVM
        variant.
    """
    _check_renderable(scene, config.width * config.height, config, "render")
    camera = scene.view(view) if isinstance(view, str) else view
    source = _CameraSource(
        camera, jnp.asarray(config.width, jnp.int32), jnp.asarray(config.height, jnp.int32)
    )
    mean, var = _accumulate(
        scene, source, config.width * config.height, config, _seed(key), caster, 0, "path"
    )
    shape = (config.height, config.width, len(COMPONENTS), 3)
    to_img = lambda a: jnp.asarray(np.moveaxis(a.reshape(shape), 2, 0).astype(np.float32))
    return RenderResult(mean=to_img(mean), var_of_mean=to_img(var), spp=config.spp)


class RayRadiance(eqx.Module):
    """Radiance arriving along given rays, per component (see :data:`COMPONENTS`).

    Attributes:
        mean: estimated radiance travelling back along each ray, (ray, component, RGB).
        var_of_mean: estimated variance of each mean.
        spp: samples per ray.
        components: component names, in the order of the second axis.
    """

    mean: Float[Array, "n_rays n_comp 3"]
    var_of_mean: Float[Array, "n_rays n_comp 3"]
    spp: int = eqx.field(static=True)
    components: tuple[str, ...] = eqx.field(static=True, default=COMPONENTS)

    def component(self, name: str) -> Float[Array, "n_rays 3"]:
        if name not in self.components:
            raise KeyError(f"no component {name!r}; components: {self.components}")
        return self.mean[:, self.components.index(name)]


def trace_rays(
    scene: Scene,
    origins: Float[Array, "n_rays 3"],
    directions: Float[Array, "n_rays 3"],
    *,
    spp: int,
    key: Key[Array, ""] | UInt32[Array, ""] | int,
    max_depth: int = 8,
    rr_depth: int = 5,
    specular: float = 1.0,
    paths_per_batch: int = 1 << 18,
    progress: bool = False,
    caster: AbstractRayCaster | None = None,
    stream_offset: int = 0,
    backend: str = "jax",
) -> RayRadiance:
    """Path-trace the radiance arriving at ``origins`` from ``directions`` (components + variance).

    For baking: a probe texel's ray starts at the probe (no surface there, so no offset); "emission" is
    then what the first surface hit emits toward the probe (or the sky it sees), and
    ``direct + diffuse_indirect + glossy_indirect`` the radiance that surface *reflects* toward it
    (DESIGN.md "indirect means reflected"). Each of the ``spp`` samples traces the same first ray
    (jitter directions yourself by passing more rays); ray i uses random stream ``stream_offset + i``,
    so tracing in chunks with running offsets reproduces a single call.

    Args:
        scene: the scene.
        origins, directions: rays, world frame; directions unit length.
        spp: paths per ray.
        key: PRNG key or integer seed.
        max_depth, rr_depth, specular, paths_per_batch, progress: as in :class:`RenderConfig`.
        caster: ray caster (default :func:`default_caster`; ``backend="jax"`` only).
        stream_offset: index of ray 0's random-number stream.
        backend: ``"jax"`` or ``"mitsuba"`` (:class:`RenderConfig`); both draw the same random numbers.

    Returns:
        A :class:`RayRadiance` (float32).

    Raises:
        ValueError: bad ray shapes; ConfigError: bad settings (a ``caster`` with ``backend="mitsuba"``
        too); ImportError: ``backend="mitsuba"`` without Mitsuba's LLVM variant.
    """
    o = jnp.asarray(origins, jnp.float32)
    d = jnp.asarray(directions, jnp.float32)
    if o.ndim != 2 or o.shape[1] != 3 or d.shape != o.shape or o.shape[0] == 0:
        raise ValueError(f"origins and directions must both be (n_rays ≥ 1, 3), got {o.shape} and {d.shape}")
    cfg = RenderConfig(
        width=int(o.shape[0]),
        height=1,
        spp=spp,
        max_depth=max_depth,
        rr_depth=rr_depth,
        specular=specular,
        paths_per_batch=paths_per_batch,
        progress=progress,
        backend=backend,
    )
    _check_renderable(scene, int(o.shape[0]), cfg, "trace_rays")

    def batch_rays(pix0: int, p: int) -> _RayBatch:
        sl = slice(pix0, min(pix0 + p, n))
        pad = p - (sl.stop - sl.start)
        padded = lambda a: jnp.pad(a[sl], ((0, pad), (0, 0)), mode="edge")
        return _RayBatch(padded(o), padded(d))

    n = int(o.shape[0])
    mean, var = _accumulate(scene, batch_rays, n, cfg, _seed(key), caster, stream_offset, "ray")
    f32 = lambda a: jnp.asarray(a.astype(np.float32))
    return RayRadiance(mean=f32(mean), var_of_mean=f32(var), spp=spp)
