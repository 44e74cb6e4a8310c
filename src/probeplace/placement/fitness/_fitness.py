"""Placement fitness: Wang et al. 2019 Eq. 1–2, union coverage and a shading proxy, soft and binary.

The "global visibility atlas" of Wang §3.2 is, here, the scene's area-stratified surface samples
(:func:`probeplace.geometry.sample_surface`): sample i stands for a patch of area aᵢ with normal nᵢ.

**Visibility as the probe's octahedral map decides it.** A probe at p stores, per texel of an R×R
octahedral map, the distance to the first surface in that texel's direction. Sample x (distance
d = |x − p|) is in the map when the first surface along p→x is no nearer than d − tol, with tol the
texel footprint at distance d: tol = max(2h, d·θ/2), θ = √(4π)/R the mean angular texel width (R² texels
share 4π sr) and h the SDF voxel (the tracer's own resolution). A sample must also face the probe
(−ω·n > 0: a probe behind a one-sided wall sees its back, which is another atlas texel in Wang's
setting); ``two_sided`` drops that test. A probe inside a solid sees nothing.

* binary V (``_binary``): the SDF sphere tracer (:func:`probeplace.geometry.trace_sdf_rays`) or an exact
  caster;
* soft V: the minimum-clearance soft visibility of :func:`probeplace.geometry.soft_visibility`
  (σ((minᵢ cᵢ − τ)/s), cᵢ = (f(tᵢ) + f(tᵢ₊₁) − Δᵢ)/2 a Lipschitz lower bound of the clearance of each
  interval), evaluated here on the segment from the probe to the sample *lifted* by ε = τ + 3s along its
  normal, with intervals growing geometrically away from the sample (tᵢ ∝ e^{βi/(N−1)} − 1, β = 4). Evenly
  spaced points read every segment that ends on a surface at less than ~45° as mostly blocked (the bound
  needs f(tᵢ) + f(tᵢ₊₁) > Δ + 2τ while f ≈ t·cos near the end); fine intervals near the sample and the lift
  make an unblocked sample read ≈ σ(3) ≈ 0.95 instead. Times a logistic facing weight σ(−ω·n/κ).
  Differentiable in the probe position.

**Wang's fitness (Eq. 1–2)**, literally: R(P) = Σᵢ πᵢ, πᵢ = Σₖ (w₁ Ω̄ᵢₖ + w₂ d̄ₖ) Vᵢₖ with
Ω̄ᵢₖ = −ωᵢₖ·nᵢ (ω the direction from probe k to sample i) and d̄ₖ = Σ_ω |p̄ₖ − p(ω)| the sum of the
distances to all the surfaces probe k sees (Wang §3.2, "Distance to Surface"). The surface points p(ω)
probe k sees are, in the atlas, the samples it sees, so the sum over its directions is taken over the
atlas: d̄ₖ = Σᵢ (aᵢ/A) Vᵢₖ |pₖ − xᵢ| / L. That is a smooth function of pₖ (the Euclidean probe–sample
distance times the soft visibility), so its gradient is exact; the distance to the first surface along a
traced direction is not (the tracer's hit is piecewise in pₖ wherever the hit jumps between surfaces).
Two normalisations, both constant factors absorbed into w₁, w₂: the texel sum Σᵢ becomes the
area-weighted sum Σᵢ aᵢ/A (Wang's atlas texels have about equal area; our samples carry their area), and
d̄ₖ is divided by the scene diagonal L, so d̄ₖ ∈ [0, 1] and w₂ is dimensionless.

**Union coverage**: C(P) = Σᵢ aᵢ/A · (1 − Πₖ (1 − Vᵢₖ)), a noisy-OR: a sample seen by three probes is
not three times as covered (DESIGN.md), and C ∈ [0, 1] is the soft share of area seen.

**Shading** (:func:`shading_objective`): how well the best probe can stand in for a sample's incident
light. Per sample i and probe k, q_ik = max(0, cos θ_ik) · 1/(1 + d_ik²/s²) · V_ik, θ the angle between
the sample normal and the direction to the probe, d the distance, s = L/8 and V the soft visibility:
irradiance probes reproduce a surface's shading best when one sits in front of it (cos θ: a probe seen at
grazing angle samples the light on the wrong side of the surface) and near it (the solid angle a patch
subtends at the probe falls as 1/d²; the 1 + d²/s² form stays finite at d → 0 and is 1/2 at d = s). The
best probe counts, not the sum — a renderer interpolates the nearest probes, it does not add them — taken
softly by the Boltzmann operator Σₖ qₖ softmaxₖ(q/t) (t = 0.05: ≤ max q, exactly q for one probe,
smooth), then the area-weighted mean over coverable samples. In [0, 1]; unlike coverage it keeps
rewarding better positions after every sample is seen.

Samples that no feasible probe can see head-on (the floor under a block, a block's underside, a flat roof
at the top of the box, the inside of slits thinner than the probe clearance) are *not coverable*
(:func:`coverable_mask`). Their weight is zero in both objectives and they are left out of coverage
(:attr:`PlacementProblem.coverable`).
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from ..._core import ConfigError, Scene, next_pow2, safe_norm
from ...geometry import SDFGrid, SurfaceSamples, build_sdf, lookup_sdf, sample_surface, sdf_value
from ..space import ReachableSpace, default_clearance, reachable_space, view_positions
from ._field import tighten_sdf


def dynamic_float(v):
    """Converter of a swept float field: a Python number becomes a NumPy float64 scalar.

    On the host it is still a ``float`` (JSON, comparisons, f-strings read it as before), but
    ``eqx.filter_jit`` sees an array, so it is traced rather than baked into the compiled code: a sweep
    over the value compiles once. Code that computes with it casts it to the dtype at hand
    (``jnp.asarray(v, dtype)``): a traced float64 would otherwise promote float32 arithmetic.
    """
    if isinstance(v, int | float) and not isinstance(v, bool):
        return np.float64(v)
    return v


#: What counts toward coverage (``FitnessConfig.coverage``).
COVERAGE_RULES = ("reachable", "views")


class FitnessConfig(eqx.Module):
    """Parameters of the fitness (see the module docstring).

    The float fields are dynamic (:func:`dynamic_float`: traced under ``jax.jit``/``eqx.filter_jit``, so
    sweeping them never recompiles); ``map_res``, ``n_steps`` and ``two_sided`` shape the computation and
    are static.

    Attributes:
        w1: weight of the solid-angle term Ω̄ = −ω·n (Wang Eq. 2).
        w2: weight of the distance term d̄ (Wang Eq. 2; normalised by the scene diagonal).
        map_res: octahedral map resolution R deciding visibility (static).
        sharpness_voxels: soft-visibility transition width s, in SDF voxels.
        n_steps: samples along each probe→sample segment for soft visibility (static).
        facing_softness: κ of the logistic facing weight σ(−ω·n/κ).
        two_sided: samples are seen from both sides (static).
        clearance_voxels: a probe position is feasible when its SDF value is at least this many voxels.
        coverage: which surface counts toward coverage (static): ``"reachable"`` (default: every sample a
            probe in the views' reachable space can see head-on, :func:`coverable_mask`) or ``"views"``
            (of those, only the samples some view camera's position sees, :func:`seen_from_views`: the
            surfaces a player at the views can see, Wang 2019's playable space; issue 34).
    """

    w1: float = eqx.field(default=1.0, converter=dynamic_float)
    w2: float = eqx.field(default=1.0, converter=dynamic_float)
    map_res: int = eqx.field(static=True, default=64)
    sharpness_voxels: float = eqx.field(default=0.5, converter=dynamic_float)
    n_steps: int = eqx.field(static=True, default=32)
    facing_softness: float = eqx.field(default=0.1, converter=dynamic_float)
    two_sided: bool = eqx.field(static=True, default=False)
    clearance_voxels: float = eqx.field(default=2.0, converter=dynamic_float)
    coverage: str = eqx.field(static=True, default="reachable")

    def __check_init__(self):
        # a stored float64 is checked and shown as the float it was given (``nan``, not ``np.float64(nan)``)
        def given(name):
            v = getattr(self, name)
            return float(v) if isinstance(v, np.floating) else v

        for name in ("sharpness_voxels", "facing_softness", "clearance_voxels"):
            v = given(name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise ConfigError(f"FitnessConfig.{name} must be a positive number, got {v!r}")
        for name in ("w1", "w2"):
            v = given(name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise ConfigError(f"FitnessConfig.{name} must be a non-negative number, got {v!r}")
        for name in ("map_res", "n_steps"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | np.integer):
                raise ConfigError(f"FitnessConfig.{name} must be an integer, got {v!r}")
        if self.map_res < 1 or self.n_steps < 2:
            raise ConfigError("FitnessConfig: map_res ≥ 1 and n_steps ≥ 2 are required")
        if self.coverage not in COVERAGE_RULES:
            raise ConfigError(
                f"FitnessConfig.coverage must be one of {COVERAGE_RULES}, got {self.coverage!r}"
            )


class PlacementProblem(eqx.Module):
    """Everything the fitness needs, fixed for a run (the *model*, STYLE §2).

    Attributes:
        grid: the scene's SDF.
        position, normal: the surface samples (the atlas), world frame.
        weight: aᵢ/A over coverable samples (zero for the others); sums to 1.
        coverable: whether a probe inside the box can see the sample at all (module docstring).
        lo, hi: the placement box (the scene bounds), world frame.
        diag: scene diagonal L, scene units.
        config: the fitness parameters.
    """

    grid: SDFGrid
    position: Float[Array, "n 3"]
    normal: Float[Array, "n 3"]
    weight: Float[Array, " n"]
    area: Float[Array, " n"]
    coverable: Bool[Array, " n"]
    lo: Float[Array, "3"]
    hi: Float[Array, "3"]
    diag: Float[Array, ""]
    config: FitnessConfig

    @property
    def n_samples(self) -> int:
        return int(self.position.shape[0])

    @property
    def voxel(self) -> Float[Array, ""]:
        return self.grid.voxel_size.astype(self.position.dtype)

    @property
    def thickness(self) -> Float[Array, ""]:
        """τ: the interpolated field's largest value on a one-sided sheet, h√3/2 (docs/sdf.md)."""
        return self.voxel * (math.sqrt(3.0) / 2.0)

    @property
    def lift(self) -> Float[Array, ""]:
        """ε = τ + 3s: how far soft visibility lifts a sample off its surface."""
        h = self.voxel
        return self.thickness + 3.0 * jnp.asarray(self.config.sharpness_voxels, h.dtype) * h

    @property
    def clearance(self) -> Float[Array, ""]:
        """Smallest feasible probe-to-surface distance, scene units."""
        h = self.voxel
        return jnp.asarray(self.config.clearance_voxels, h.dtype) * h


def _normal_march(grid: SDFGrid, lo, hi, clearance: float, diag: float, position, normal):
    """Per sample: whether a feasible probe sees it head-on, and the deepest such point on its normal."""
    h = float(grid.voxel_size)
    t = np.geomspace(2.0 * h, max(0.5 * diag, 4.0 * h), 40).astype(np.float32)
    tau = h * math.sqrt(3.0) / 2.0
    # one jitted program (eager, the march's setup ops compiled one by one)
    return _normal_march_jit(
        grid,
        jnp.asarray(lo),
        jnp.asarray(hi),
        jnp.float32(clearance),
        jnp.float32(tau),
        jnp.asarray(t),
        jnp.asarray(np.diff(t)),
        jnp.asarray(position),
        jnp.asarray(normal),
    )


@eqx.filter_jit
def _normal_march_jit(grid: SDFGrid, lo, hi, clearance, tau, tt, dt, position, normal):

    def one(x, n):
        q = x[None, :] + tt[:, None] * n[None, :]
        f = jax.vmap(lambda y: sdf_value(grid, y))(q)
        in_box = jnp.all((q >= lo[None]) & (q <= hi[None]), axis=-1)
        # An interval is clear when the Lipschitz bound (f_i + f_{i+1} − Δ_i)/2 stays above τ = h√3/2 (the
        # most a one-sided sheet reads after interpolation); the first 2h are forgiven as in
        # binary_visibility.
        seg_ok = jnp.concatenate([f[:1] > tau, (f[:-1] + f[1:] - dt) > 2.0 * tau])
        clear_so_far = jnp.cumprod(seg_ok.astype(jnp.int32)) > 0
        ok = clear_so_far & in_box & (f >= clearance)
        best = jnp.argmax(jnp.where(ok, f, -jnp.inf))
        return jnp.any(ok), q[best]

    return jax.lax.map(lambda xn: one(*xn), (position, normal), batch_size=4096)


def seen_from_views(scene: Scene, samples: SurfaceSamples, *, two_sided: bool = False) -> np.ndarray:
    """Samples that some view camera's *position* sees (any direction: not limited to its frustum): the
    sample faces the camera (unless ``two_sided``) and the segment from the camera to the sample, lifted
    off the surface by 1e-4 of the scene diagonal toward the camera's side, is free (exact ray casting).
    A scene without views sees nothing: refused, since coverage would be empty.

    Raises:
        ConfigError: the scene has no views.
    """
    from ...geometry import make_caster

    cams = view_positions(scene).reshape(-1, 3)
    if len(cams) == 0:
        raise ConfigError(
            f"coverage='views' needs the scene's view cameras, and {scene.name!r} has none: add views or "
            "use coverage='reachable'"
        )
    caster = make_caster(scene)
    x = np.asarray(samples.position, np.float64)
    n = np.asarray(samples.normal, np.float64)
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    lift = 1e-4 * float(np.linalg.norm(hi - lo))
    seen = np.zeros(len(x), bool)
    for c in cams:
        to_cam = c[None, :] - x
        facing = np.sum(n * to_cam, axis=1)
        side = np.where(facing >= 0, 1.0, -1.0)[:, None]
        start = x + lift * side * n
        v = c[None, :] - start
        dist = np.linalg.norm(v, axis=1)
        ok = (dist > 0) & (two_sided | (facing > 0)) & ~seen
        if not ok.any():
            continue
        d = v[ok] / dist[ok, None]
        o32, d32, t32 = (x.astype(np.float32) for x in (start[ok], d, dist[ok]))
        seen[np.flatnonzero(ok)[~caster.occluded_host(o32, d32, t32)]] = True
    return seen


def coverable_mask(
    grid: SDFGrid,
    samples: SurfaceSamples,
    lo: Array,
    hi: Array,
    clearance: float,
    diag: float,
    *,
    reach: ReachableSpace | None = None,
) -> np.ndarray:
    """Samples some feasible probe can see head-on (module docstring).

    Sample x is coverable when, marching along its normal n, the segment x + t·n (t from 2h to L/2,
    40 geometric steps, each interval cleared by the Lipschitz bound (f_i + f_{i+1} − Δ_i)/2 > τ) stays in
    free
    space up to a t where the point is inside the box [lo, hi] and at
    least ``clearance`` from every surface: a probe there sees x along −n. This excludes the floor under
    a block, a block's underside, a flat roof at the top of the box and slits thinner than the probe
    clearance (the gap between a pillar and the roof above it). With ``reach`` (``_reach``) that point must
    also be reachable from the views: a roof's top or a vault's back is seen only from sealed-off space.
    """
    ok, q = _normal_march(grid, lo, hi, clearance, diag, samples.position, samples.normal)
    ok = np.asarray(ok)
    if reach is not None:
        ok = ok & reach.contains(np.asarray(q))
    return ok


def witness_positions(problem: PlacementProblem, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For samples ``idx``: (has a witness, the deepest feasible point on the normal that sees it head-on)."""
    idx = np.asarray(idx, np.int64).ravel()
    n = len(idx)
    # padded to a power of two: the search calls this with varying counts, a few compilations serve all
    pad = np.zeros(next_pow2(n, lo=8), np.int64)
    pad[:n] = idx
    ok, q = _normal_march(
        problem.grid,
        problem.lo,
        problem.hi,
        float(problem.clearance),
        float(problem.diag),
        problem.position[pad],
        problem.normal[pad],
    )
    return np.asarray(ok)[:n], np.asarray(q, np.float32)[:n]


def make_problem(
    scene: Scene,
    *,
    key: jax.Array,
    grid: SDFGrid | None = None,
    samples: SurfaceSamples | None = None,
    n_samples: int | None = None,
    config: FitnessConfig | None = None,
    cache_dir=None,
    reach_clearance: float | None = None,
) -> PlacementProblem:
    """Build the fitness model of a scene (host work: SDF build, surface samples, coverable mask).

    Args:
        scene: the scene; the placement box is its bounds.
        key: PRNG key for the surface samples.
        grid: the SDF; built (and cached) with default resolution when ``None``. Its far field is raised
            with :func:`tighten_sdf` either way.
        samples: the atlas; when ``None`` drawn at the default density, or at about ``n_samples`` samples
            (area-stratified at spacing √(A/n_samples), without the one-per-triangle floor so that a
            many-triangle mesh still gets about that many) — optimisation uses a few thousand.
        n_samples: see ``samples``.
        config: fitness parameters.
        cache_dir: passed to :func:`probeplace.geometry.build_sdf`.
        reach_clearance: the probe clearance of the reachable space that witnesses must lie in (the
            placement request's ``clearance``, so coverable samples and valid probes agree); ``None``:
            :func:`~._valid.default_clearance`.

    Raises:
        ConfigError: ``n_samples`` not positive.
    """
    config = FitnessConfig() if config is None else config
    if grid is None:
        grid = build_sdf(scene) if cache_dir is None else build_sdf(scene, cache_dir=cache_dir)
    # the valid space's reach (_reach; the raw grid, as make_valid reads it): a sample whose only witnesses
    # are sealed off from the views (Sponza's roof tops, vault backs) is not coverable
    if reach_clearance is None:
        reach_clearance = default_clearance(scene, grid)
    reach = reachable_space(grid, float(reach_clearance), view_positions(scene))
    grid, _ = tighten_sdf(grid)
    if samples is None:
        spacing = None
        if n_samples is not None:
            if n_samples < 1:
                raise ConfigError(f"n_samples must be positive, got {n_samples}")
            tri = np.asarray(scene.vertices, np.float64)[np.asarray(scene.faces)]
            area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
            spacing = float(np.sqrt(area / n_samples))
        samples = sample_surface(scene, key=key, spacing=spacing, min_one=spacing is None)
    lo, hi = scene.bounds[0], scene.bounds[1]
    diag = float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))
    clearance = config.clearance_voxels * float(grid.voxel_size)
    cov = coverable_mask(grid, samples, lo, hi, clearance, diag, reach=reach)
    if config.two_sided:
        back = SurfaceSamples(samples.position, -samples.normal, samples.area, samples.material, samples.tri)
        cov = cov | coverable_mask(grid, back, lo, hi, clearance, diag, reach=reach)
    if config.coverage == "views":
        cov = cov & seen_from_views(scene, samples, two_sided=config.two_sided)
    area = np.asarray(samples.area, np.float64)
    w = np.where(cov, area, 0.0)
    w = w / max(w.sum(), 1e-300)
    return PlacementProblem(
        grid=grid,
        position=samples.position,
        normal=samples.normal,
        weight=jnp.asarray(w, jnp.float32),
        area=samples.area,
        coverable=jnp.asarray(cov),
        lo=jnp.asarray(lo, jnp.float32),
        hi=jnp.asarray(hi, jnp.float32),
        diag=jnp.asarray(np.linalg.norm(np.asarray(hi) - np.asarray(lo)), jnp.float32),
        config=config,
    )


def _texel_angle(res: int) -> float:
    """Mean angular width of a texel of an R×R octahedral map: √(4π/R²)."""
    return math.sqrt(4.0 * math.pi) / res


def _tolerance(problem: PlacementProblem, d: Array) -> Array:
    """Texel footprint at distance d, never below 2 voxels (module docstring)."""
    h = problem.voxel.astype(d.dtype)
    return jnp.maximum(2.0 * h, d * (_texel_angle(problem.config.map_res) / 2.0))


class ProbeColumn(eqx.Module):
    """One probe's view of the atlas: soft visibility Vᵢ (facing included) and Ω̄ᵢ = −ωᵢ·nᵢ."""

    vis: Float[Array, " n"]
    omega: Float[Array, " n"]


_BETA = 4.0  # geometric growth of the soft-visibility intervals away from the sample


def _segment_visibility(problem: PlacementProblem, p: Array, target: Array, skip: Array) -> Array:
    """Soft visibility of ``target`` from ``p`` (module docstring); ``skip`` is dropped at the target end."""
    cfg = problem.config
    dtype = p.dtype
    h = problem.voxel.astype(dtype)
    s = jnp.asarray(cfg.sharpness_voxels, dtype) * h
    tau = problem.thickness.astype(dtype)
    seg = p - target  # from the sample toward the probe
    length = safe_norm(seg)
    inner = length - skip - 2.0 * h  # the probe end keeps a 2h margin like soft_visibility
    ok = inner > 0
    inner_safe = jnp.where(ok, inner, 1.0)
    length_safe = jnp.where(ok, length, 1.0)
    k = jnp.arange(cfg.n_steps, dtype=dtype) / (cfg.n_steps - 1)
    frac = jnp.expm1(_BETA * k) / math.expm1(_BETA)
    t = skip + inner_safe * frac
    pts = target[None, :] + (t / length_safe)[:, None] * seg[None, :]
    f = jax.vmap(lambda q: sdf_value(problem.grid, q))(pts)
    c = (f[:-1] + f[1:] - (t[1:] - t[:-1])) / 2.0
    v = jax.nn.sigmoid((jnp.min(c) - tau) / s)
    return jnp.where(ok, v, jnp.ones((), dtype))


def probe_column(problem: PlacementProblem, p: Float[Array, "3"]) -> ProbeColumn:
    """Soft visibility of every sample from ONE probe at ``p`` (differentiable in ``p``)."""
    cfg = problem.config
    dtype = p.dtype
    x = problem.position.astype(dtype)
    n = problem.normal.astype(dtype)
    h = problem.voxel.astype(dtype)
    v = x - p[None, :]
    d = safe_norm(v)
    d_safe = jnp.where(d > 0, d, 1.0)
    omega_dir = v / d_safe[:, None]  # ω: probe → sample
    cos = -jnp.sum(omega_dir * n, axis=-1)  # Wang's Ω̄ = −ω·n
    tol = _tolerance(problem, d)
    lift = problem.lift.astype(dtype)
    side = jnp.sign(cos) if cfg.two_sided else jnp.ones_like(cos)
    # The target is lifted off the surface by ε along the (probe-side) normal, then pulled back toward
    # the probe by the rest of the texel footprint: see _segment_visibility.
    target = x + (side * lift)[:, None] * n
    vis = jax.vmap(lambda xx, tt: _segment_visibility(problem, p, xx, tt))(
        target, jnp.maximum(tol - lift, 0.0)
    )
    kappa = jnp.asarray(cfg.facing_softness, dtype)
    if cfg.two_sided:
        omega = jnp.sqrt(cos * cos + jnp.asarray(1e-12, dtype))
    else:
        # XLA compiles ÷ by a constant κ as × 1/κ: a traced κ (a swept config) takes the product too, so
        # it gives bit for bit what a constant κ gives, under jit and eagerly alike
        traced = isinstance(kappa, jax.core.Tracer)
        vis = vis * jax.nn.sigmoid(cos * (1.0 / kappa) if traced else cos / kappa)
        omega = cos
    # A probe inside a solid sees nothing: its own clearance gates every sample.
    inside = jax.nn.sigmoid(sdf_value(problem.grid, p) / (jnp.asarray(cfg.sharpness_voxels, dtype) * h))
    return ProbeColumn(vis=vis * inside, omega=omega)


def probe_distance_term(
    problem: PlacementProblem, p: Float[Array, "3"], vis: Float[Array, " n"] | None = None
) -> Float[Array, ""]:
    """d̄ of ONE probe: Σᵢ (aᵢ/A) Vᵢ |p − xᵢ| / L, Wang Eq. 2's distance term over the atlas (module doc).

    Args:
        problem: the fitness model.
        p: the probe position.
        vis: its visibility column Vᵢ (soft or binary); :func:`probe_column`'s soft one when ``None``.

    Smooth in ``p`` (the Euclidean probe–sample distance and the soft visibility), so the analytic
    gradient matches finite differences.
    """
    vis = probe_column(problem, p).vis if vis is None else vis
    dtype = p.dtype
    d = safe_norm(problem.position.astype(dtype) - p[None, :])
    return jnp.sum(problem.weight.astype(dtype) * vis.astype(dtype) * d) / problem.diag.astype(dtype)


def wang_from_columns(
    problem: PlacementProblem, vis: Array, omega: Array, dbar: Array, active: Array
) -> Float[Array, ""]:
    """Eq. 1–2 from per-probe columns: Σᵢ aᵢ Σₖ (w₁ Ω̄ᵢₖ + w₂ d̄ₖ) Vᵢₖ (inactive probes excluded)."""
    cfg = problem.config
    dtype = vis.dtype
    w = problem.weight.astype(dtype)
    w1, w2 = jnp.asarray(cfg.w1, dtype), jnp.asarray(cfg.w2, dtype)
    term = (w1 * omega + w2 * dbar[:, None]) * vis  # (n_probes, n)
    term = jnp.where(active[:, None], term, 0.0)
    return jnp.sum(term @ w)


def coverage_from_columns(problem: PlacementProblem, vis: Array, active: Array) -> Float[Array, ""]:
    """Union coverage Σᵢ aᵢ (1 − Πₖ (1 − Vᵢₖ)) from per-probe columns."""
    q = jnp.where(active[:, None], vis, 0.0)
    miss = jnp.prod(1.0 - q, axis=0)
    return jnp.sum(problem.weight.astype(vis.dtype) * (1.0 - miss))


def _columns(problem: PlacementProblem, pos: Array) -> ProbeColumn:
    return jax.vmap(lambda p: probe_column(problem, p))(pos)


def wang_fitness(
    problem: PlacementProblem, pos: Float[Array, "n_probes 3"], active: Bool[Array, " n_probes"] | None = None
) -> Float[Array, ""]:
    """Wang et al. 2019 Eq. 1–2 with soft visibility (module docstring); differentiable in ``pos``."""
    active = jnp.ones(pos.shape[0], bool) if active is None else active
    col = _columns(problem, pos)
    dbar = jax.vmap(lambda p, v: probe_distance_term(problem, p, v))(pos, col.vis)
    return wang_from_columns(problem, col.vis, col.omega, dbar, active)


def coverage_objective(
    problem: PlacementProblem, pos: Float[Array, "n_probes 3"], active: Bool[Array, " n_probes"] | None = None
) -> Float[Array, ""]:
    """Soft union coverage in [0, 1] (module docstring); differentiable in ``pos``."""
    active = jnp.ones(pos.shape[0], bool) if active is None else active
    return coverage_from_columns(problem, _columns(problem, pos).vis, active)


#: Shading falloff scale s as a fraction of the scene diagonal, and the soft-max temperature t.
SHADING_FALLOFF = 1.0 / 8.0
SHADING_TEMPERATURE = 0.05


def shading_column(problem: PlacementProblem, p: Float[Array, "3"]) -> Float[Array, " n"]:
    """q_i of ONE probe: max(0, cos θ)·1/(1 + d²/s²)·V (module docstring); differentiable in ``p``."""
    dtype = p.dtype
    col = probe_column(problem, p)
    d2 = jnp.sum((problem.position.astype(dtype) - p[None, :]) ** 2, axis=-1)
    s = problem.diag.astype(dtype) * jnp.asarray(SHADING_FALLOFF, dtype)
    return jnp.maximum(col.omega, 0.0) * col.vis / (1.0 + d2 / (s * s))


def shading_from_columns(problem: PlacementProblem, q: Array, active: Array) -> Float[Array, ""]:
    """Σᵢ aᵢ/A Σₖ qᵢₖ softmaxₖ(qᵢₖ/t) over active probes (module docstring)."""
    dtype = q.dtype
    t = jnp.asarray(SHADING_TEMPERATURE, dtype)
    logits = jnp.where(active[:, None], q / t, jnp.asarray(-1e30, dtype))  # inactive: weight 0
    soft = jnp.sum(jax.nn.softmax(logits, axis=0) * jnp.where(active[:, None], q, 0.0), axis=0)
    return jnp.sum(problem.weight.astype(dtype) * soft)


def shading_objective(
    problem: PlacementProblem, pos: Float[Array, "n_probes 3"], active: Bool[Array, " n_probes"] | None = None
) -> Float[Array, ""]:
    """Shading-quality proxy in [0, 1] (module docstring); differentiable in ``pos``."""
    active = jnp.ones(pos.shape[0], bool) if active is None else active
    return shading_from_columns(problem, jax.vmap(lambda p: shading_column(problem, p))(pos), active)


def probe_clearance(problem: PlacementProblem, pos) -> np.ndarray:
    """SDF value at each probe (negative: inside geometry).

    Host helper (:func:`probeplace.geometry.lookup_sdf`): the search's many calls with varying probe
    counts share a few compilations.
    """
    return lookup_sdf(problem.grid, np.asarray(pos, np.float32))
