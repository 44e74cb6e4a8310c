"""Light-field probe ray tracing (McGuire et al. 2017 §4; hi-Z variant of Wang et al. 2019 §4.2).

**Single probe.** A ray segment seen from a probe splits at the three coordinate planes through the probe
into ≤ 4 pieces, one per octant; on each octant face the octahedral map is a central projection followed
by an affine fold, so each piece projects to a *straight* 2D segment (McGuire §4.1, "a line segment maps
to a polyline with at most four segments"). Every texel-grid line u = c on the face is the plane
(a_u − c·s)·q = 0 through the probe (s the octant's signs, a_u the face's numerator), so the ray parameter
where the march enters or leaves a texel is the root of a *linear* equation: the march steps exactly from
texel to texel in ray distance t (a DDA, Amanatides & Woo 1987), never in approximate 2D steps.

Each texel is a surfel (McGuire §4.1: "a planar patch at distance r with normal n"): the plane through
x = r·ω_c with the baked normal. Within the texel's cone the ray is *in front* of the surfel (on the
probe's side of its plane), *crosses* it, or is *behind* it. A crossing toward the surfel's front side is
a hit at the exact plane crossing; a crossing of a back face is rejected with the normal map (McGuire:
"we can exclude back face intersections relative to the ray"); a ray behind the surfel by more than the
surface *thickness* has entered space the probe cannot see → unknown, stopping at the texel's entry (the
last point the probe saw in free space). Inside the thickness shell a ray moving deeper is a hit, one
moving out continues (a surfel is only a planar approximation of a curved surface).

**Hierarchy.** For every texel we precompute a conservative lower bound of its surfel's radial distance
over the texel's cone (the plane sampled at the texel's centre, corners and edge midpoints, less 2%),
and min-MIP it. If the ray's largest radial distance over a cell's t-interval (the ray's distance from
the probe is convex in t, so the larger end value) is below the cell's bound, every fine texel of the cell
would say "in front": the cell is skipped whole. ``two_level`` is McGuire's scheme (a coarse level at
1/16 the resolution per axis, then the fine level inside each coarse cell that may hold a hit);
``hiz`` is Wang's full hierarchy (Uludag 2014 hi-Z: after a skip go one level coarser, on a possible
hit go one finer), capped below the coarsest levels ("we conservatively avoid the coarsest levels").
``flat`` marches every fine texel (a reference for the tests).

**Many probes.** McGuire's Listing 1: trace one probe; on *unknown* advance the ray's start to the point
reached and try the next probe. Uniform grids: the cage of eight probes around the current point, starting
with the probe nearest the ray's line, then (i+3) mod 8 while the point stays in the same cage (§4.1).
Other sets: the ranked candidates of the voxel containing the current point (Wang §4.1). A ray tries at
most ``max_probes`` distinct probes and never revisits one; if no probe resolves it, it is *unresolved*
(counted by the callers, never passed off as a hit or miss).
"""

from __future__ import annotations

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from .._core import ConfigError, LightFieldProbes, strip_border, texel_directions
from .._core._octahedral import _octahedron_point
from ._bake import _warn_probe_layout
from ._index import GridIndex, VoxelIndex, grid_index, voxel_index

MISS, HIT, UNKNOWN = 0, 1, 2
#: Status codes of :class:`TraceResult` (``UNRESOLVED``: no probe could decide).
RAY_MISS, RAY_HIT, RAY_UNRESOLVED = 0, 1, 2
HIERARCHIES = ("hiz", "two_level", "flat")


@dataclasses.dataclass(frozen=True, kw_only=True)
class TraceConfig:
    """Light-field tracer settings.

    Attributes:
        hierarchy: ``"hiz"`` (Wang 2019 §4.2), ``"two_level"`` (McGuire 2017 §4.2) or ``"flat"``.
        coarse_factor: two-level: the coarse level is this many times coarser per axis (McGuire: 16).
        hiz_skip_top: hi-Z: how many of the coarsest MIP levels to leave out (Wang: "avoid the coarsest").
        thickness: surface thickness as a fraction of the surfel's radial distance (McGuire's
            ``minThickness``/``maxThickness`` scale with distance the same way).
        max_probes: distinct probes a ray may try before it is unresolved (McGuire: the 8 of a cage).
        max_steps: texel steps per octant piece of a single-probe trace (``None``: 6 × the resolution).
        bounds_margin: rays stop this far (fraction of the largest scene extent) outside the scene box.
    """

    hierarchy: str = "hiz"
    coarse_factor: int = 16
    hiz_skip_top: int = 1
    thickness: float = 0.03
    max_probes: int = 8
    max_steps: int | None = None
    bounds_margin: float = 0.05

    def __post_init__(self):
        for name in ("coarse_factor", "hiz_skip_top", "max_probes", "max_steps"):
            v = getattr(self, name)
            if not (v is None and name == "max_steps") and (not isinstance(v, int) or isinstance(v, bool)):
                raise ConfigError(f"TraceConfig.{name} must be an int, got {v!r}")
        for name in ("thickness", "bounds_margin"):
            v = getattr(self, name)
            if not isinstance(v, int | float) or isinstance(v, bool) or not math.isfinite(v):
                raise ConfigError(f"TraceConfig.{name} must be a finite number, got {v!r}")
        if self.hierarchy not in HIERARCHIES:
            raise ConfigError(f"TraceConfig.hierarchy must be one of {HIERARCHIES}, got {self.hierarchy!r}")
        if self.coarse_factor < 2 or self.coarse_factor & (self.coarse_factor - 1):
            raise ConfigError(
                f"TraceConfig.coarse_factor must be a power of two ≥ 2, got {self.coarse_factor}"
            )
        if self.hiz_skip_top < 0:
            raise ConfigError(f"TraceConfig.hiz_skip_top must be ≥ 0, got {self.hiz_skip_top}")
        if not (0.0 <= self.thickness < 1.0):
            raise ConfigError(f"TraceConfig.thickness must be in [0, 1), got {self.thickness}")
        if self.max_probes < 1:
            raise ConfigError(f"TraceConfig.max_probes must be ≥ 1, got {self.max_probes}")
        if not self.bounds_margin >= 0:
            raise ConfigError(f"TraceConfig.bounds_margin must be ≥ 0, got {self.bounds_margin}")
        if self.max_steps is not None and self.max_steps < 1:
            raise ConfigError(f"TraceConfig.max_steps must be ≥ 1, got {self.max_steps}")


class LightFieldTracer(eqx.Module):
    """Everything the tracer reads, precomputed from :class:`LightFieldProbes` (build with
    :func:`make_tracer`).

    Attributes:
        pos_world: probe centres.
        usable: probes the tracer may use (active, not inside geometry).
        surfel_x: per interior texel, the surfel point relative to the probe, r·ω_c (zeros: no surface).
        surfel_n: the surfel's (front-side) normal from the normal map.
        has_surface: the texel's ray hit something (its distance is below ``far``).
        bound_flat: per probe, the conservative lower bounds of all MIP levels 0 (R²) … top, flattened.
        far: distance stored for escaping rays.
        t_far: largest ray distance traced (the scene bounds' diagonal).
        bounds: the scene's (min, max) corners, inflated by ``bounds_margin``; nothing lies outside, so a
            ray is traced only until it leaves them (Wang 2019 §5: visibility is bounded by the scene
            bounds). The margin lets a ray that slips through a wall inside one texel (whose surfel is
            another surface) go on to be *behind* that wall, hence unknown, rather than a false miss.
        index: the probe-selection index.
        res: interior map resolution R (static).
        config: settings (static).
    """

    pos_world: Float[Array, "n_probes 3"]
    usable: Bool[Array, " n_probes"]
    surfel_x: Float[Array, "n_probes r r 3"]
    surfel_n: Float[Array, "n_probes r r 3"]
    has_surface: Bool[Array, "n_probes r r"]
    bound_flat: Float[Array, "n_probes m"]
    far: Float[Array, ""]
    t_far: Float[Array, ""]
    bounds: Float[Array, "2 3"]
    index: GridIndex | VoxelIndex
    res: int = eqx.field(static=True)
    config: TraceConfig = eqx.field(static=True)

    @property
    def n_levels(self) -> int:
        return int(math.log2(self.res)) + 1

    def level_offset(self, level: int) -> int:
        return sum((self.res >> k) ** 2 for k in range(level))


class TraceResult(eqx.Module):
    """Per ray: status (0 miss, 1 hit, 2 unresolved), hit distance (inf unless hit; for unresolved rays
    the last point known to be free), probe and fine texel (row, col) that resolved the hit, texel steps
    and probes tried."""

    status: Int[Array, " n_rays"]
    t: Float[Array, " n_rays"]
    probe: Int[Array, " n_rays"]
    texel: Int[Array, "n_rays 2"]
    steps: Int[Array, " n_rays"]
    probes_tried: Int[Array, " n_rays"]

    @property
    def hit(self) -> Bool[Array, " n_rays"]:
        return self.status == RAY_HIT

    @property
    def unresolved(self) -> Bool[Array, " n_rays"]:
        return self.status == RAY_UNRESOLVED


# --------------------------------------------------------------------------------------------- building
def _surfel_bounds(x: Array, n: Array, has: Array, res: int, big: float) -> Array:
    """Lower bound of each surfel plane's radial distance over its texel's cone (module docstring)."""
    h = 2.0 / res
    c = (jnp.arange(res, dtype=x.dtype) + 0.5) * h - 1.0
    offs = jnp.asarray([-0.5, 0.0, 0.5], x.dtype) * h
    ou, ov = jnp.meshgrid(offs, offs, indexing="ij")
    uu = c[None, :, None] + ou.reshape(-1)[None, None, :]  # (1, R, 9) u per column
    vv = c[:, None, None] + ov.reshape(-1)[None, None, :]  # (R, 1, 9)
    uv = jnp.stack(jnp.broadcast_arrays(uu, vv), axis=-1)  # (R, R, 9, 2)
    p = _octahedron_point(jnp.clip(uv, -1.0, 1.0))
    w = p / jnp.linalg.norm(p, axis=-1, keepdims=True)  # (R, R, 9, 3)
    # Plane through x with normal n: points q with (q − x)·n = 0; along ω at r = (x·n)/(ω·n) if positive.
    xn = jnp.sum(x * n, axis=-1)[..., None]  # (P, R, R, 1)
    wn = jnp.einsum("ijkc,pijc->pijk", w, n)
    ok = (wn * xn > 0) & (jnp.abs(wn) > 1e-6)
    r = jnp.where(ok, xn / jnp.where(ok, wn, 1.0), big)
    lo = jnp.min(r, axis=-1) * 0.98  # 2% margin: the plane is sampled at 9 points, not bounded exactly
    return jnp.where(has, lo, big)


def make_tracer(
    lf: LightFieldProbes,
    bounds: Float[Array, "2 3"],
    *,
    index: GridIndex | VoxelIndex | None = None,
    config: TraceConfig = TraceConfig(),
) -> LightFieldTracer:
    """Precompute the tracer's maps and probe index from baked probes.

    Args:
        lf: baked light-field probes (the radial-distance and normal maps are used).
        bounds: (min, max) of the scene; rays are traced no farther than its diagonal.
        index: probe-selection index; ``None`` uses :func:`grid_index` when the probes form a full uniform
            grid, else :func:`voxel_index`.
        config: tracer settings.

    Returns:
        A :class:`LightFieldTracer` (float32).

    Raises:
        ConfigError: bad settings, non-finite probe positions or bounds, or no usable probe. Duplicate
            probes and probes outside ``bounds`` are accepted with a logged warning.
    """
    res = lf.radiance_res
    if res < 2 or res & (res - 1):
        raise ConfigError(f"the tracer needs power-of-two probe maps, got resolution {res}")
    b = jnp.asarray(bounds, jnp.float32)
    pos = np.asarray(lf.pos_world, np.float32)
    if not np.isfinite(pos).all():
        raise ConfigError(f"probe positions must be finite; {int((~np.isfinite(pos)).any(-1).sum())} are not")
    if b.shape != (2, 3) or not bool(jnp.all(jnp.isfinite(b))) or not bool(jnp.all(b[1] >= b[0])):
        raise ConfigError(f"bounds must be finite (min, max) corners of shape (2, 3), got {np.asarray(b)}")
    # Inactive rows (e.g. padding to a fixed size so compiled code is reused) are not probes: skip them.
    _warn_probe_layout(pos[np.asarray(lf.active)], np.asarray(b[0]), np.asarray(b[1]), "make_tracer")
    if index is None:
        try:
            index = grid_index(lf)
        except ConfigError:
            index = voxel_index(lf, b)
    far = jnp.asarray(lf.far, jnp.float32)
    dist = strip_border(lf.distance[..., None])[..., 0].astype(jnp.float32)
    nrm = strip_border(lf.normal).astype(jnp.float32)
    has = (dist < 0.999 * far) & (jnp.sum(nrm * nrm, axis=-1) > 0.25)
    omega = texel_directions(res, jnp.float32)
    # A surfel whose normal is missing or perpendicular to the view gets the view-facing normal.
    nrm = jnp.where(
        (jnp.abs(jnp.sum(nrm * omega[None], axis=-1)) > 1e-3)[..., None] & has[..., None], nrm, -omega[None]
    )
    x = jnp.where(has[..., None], dist[..., None] * omega[None], 0.0)
    big = float(4.0 * far)
    margin = config.bounds_margin * jnp.max(b[1] - b[0])
    level = _surfel_bounds(x, nrm, has, res, big)
    levels = [level.reshape(level.shape[0], -1)]
    while level.shape[1] > 1:
        p, r = level.shape[0], level.shape[1]
        level = level.reshape(p, r // 2, 2, r // 2, 2).min(axis=(2, 4))
        levels.append(level.reshape(p, -1))
    return LightFieldTracer(
        pos_world=jnp.asarray(lf.pos_world, jnp.float32),
        usable=jnp.asarray(lf.active) & ~jnp.asarray(lf.inside),
        surfel_x=x,
        surfel_n=nrm,
        has_surface=has,
        bound_flat=jnp.concatenate(levels, axis=1),
        far=far,
        t_far=jnp.linalg.norm(b[1] - b[0]) * 1.01,
        bounds=jnp.stack([b[0] - margin, b[1] + margin]),
        index=index,
        res=res,
        config=config,
    )


# ------------------------------------------------------------------------------------- single probe
def _levels(tr: LightFieldTracer) -> tuple[int, int]:
    """(top level the march starts at, coarse level of the two-level scheme)."""
    top = tr.n_levels - 1
    cfg = tr.config
    coarse = min(int(math.log2(cfg.coarse_factor)), top)
    if cfg.hierarchy == "hiz":
        return max(top - cfg.hiz_skip_top, 0), coarse
    if cfg.hierarchy == "two_level":
        return coarse, coarse
    return 0, 0


def _face(s: Float[Array, "3"]) -> tuple[Array, Array]:
    """Numerator vectors (a_u, a_v) of the octant face with signs s: u = a_u·q / s·q, v = a_v·q / s·q."""
    lower = s[2] < 0
    one, zero = jnp.ones_like(s[0]), jnp.zeros_like(s[0])
    a_u = jnp.stack([one, zero, jnp.where(lower, s[0] * s[2], zero)])
    a_v = jnp.stack([zero, one, jnp.where(lower, s[1] * s[2], zero)])
    return a_u, a_v


def _trace_segment(tr, p, o, d, ta, tb, state):
    """March one octant piece [ta, tb] of the ray (probe-relative origin ``o``) in probe ``p``.

    ``state`` = (status, t, steps, texel); returns it updated. Continues only while status == MISS.
    """
    cfg = tr.config
    res = tr.res
    dt = o.dtype
    top, coarse = _levels(tr)
    max_steps = cfg.max_steps or 6 * res
    offsets = jnp.asarray([tr.level_offset(k) for k in range(tr.n_levels)], jnp.int32)

    s = jnp.where(o + 0.5 * (ta + tb) * d >= 0, 1.0, -1.0).astype(dt)
    a_u, a_v = _face(s)

    def uv_at(t):
        q = o + t * d
        l1 = jnp.maximum(jnp.dot(s, q), jnp.finfo(dt).tiny)
        return jnp.clip(jnp.stack([jnp.dot(a_u, q), jnp.dot(a_v, q)]) / l1, -1.0, 1.0)

    span = tb - ta
    uv_a, uv_b = uv_at(ta + 1e-5 * span), uv_at(tb - 1e-5 * span)
    du = jnp.sign(uv_b - uv_a)  # (u, v) direction of motion on the face: u(t), v(t) are monotone

    def cell_at(t, level):
        cells = (res >> level).astype(jnp.int32) if isinstance(level, Array) else jnp.int32(res >> level)
        f = (uv_at(t) + 1.0) * (cells.astype(dt) * 0.5) + 1e-3 * du
        ij = jnp.clip(jnp.floor(f).astype(jnp.int32), 0, cells - 1)
        return ij[::-1]  # (row ↔ v, col ↔ u)

    def crossing(c, a):
        # t where the ray meets the plane (a − c·s)·q = 0 (the texel-grid line at coordinate c).
        w = a - c * s
        den = jnp.dot(w, d)
        ok = jnp.abs(den) > 1e-12
        t = jnp.where(ok, -jnp.dot(w, o) / jnp.where(ok, den, 1.0), jnp.inf)
        return jnp.where(jnp.isfinite(t), t, jnp.inf)

    def body(c):
        _status, t, steps, texel, level, ij = c
        cells = jnp.right_shift(jnp.int32(res), level)
        hcell = 2.0 / cells.astype(dt)
        lo = ij[::-1].astype(dt) * hcell - 1.0  # (u_lo, v_lo)
        c_next = jnp.where(du > 0, lo + hcell, lo)
        t_u = jnp.where(du[0] != 0, crossing(c_next[0], a_u), jnp.inf)
        t_v = jnp.where(du[1] != 0, crossing(c_next[1], a_v), jnp.inf)
        # A root behind t is where the *extended* line would cross (u, v are monotone on the face, so the
        # march never meets it): never. Roots a rounding error behind t are "now".
        eps_t = 1e-5 * (jnp.abs(t) + span)
        t_u = jnp.where(t_u >= t - eps_t, jnp.maximum(t_u, t), jnp.inf)
        t_v = jnp.where(t_v >= t - eps_t, jnp.maximum(t_v, t), jnp.inf)
        t_exit = jnp.minimum(jnp.minimum(t_u, t_v), tb)

        # Coarse test: the whole cell's ray interval in front of every surfel bound?
        flat = offsets[level] + ij[0] * cells + ij[1]
        bound = tr.bound_flat[p, flat]
        rho_max = jnp.maximum(jnp.linalg.norm(o + t * d), jnp.linalg.norm(o + t_exit * d))
        skip = rho_max < bound

        # Fine test (level 0) against the surfel plane.
        i0, j0 = jnp.clip(ij[0], 0, res - 1), jnp.clip(ij[1], 0, res - 1)
        xs = tr.surfel_x[p, i0, j0]
        nf = tr.surfel_n[p, i0, j0]
        has = tr.has_surface[p, i0, j0]
        r_s = jnp.linalg.norm(xs)
        side = jnp.where(jnp.dot(xs, nf) < 0, 1.0, -1.0).astype(dt)  # orient n toward the probe
        n_p = nf * side
        g0 = jnp.dot(o + t * d - xs, n_p)
        g1 = jnp.dot(o + t_exit * d - xs, n_p)
        tau = cfg.thickness * r_s
        front = jnp.dot(d, nf) < 0  # the ray meets the surfel's front side
        deeper = jnp.dot(d, n_p) < 0  # moving away from the probe's side of the plane
        cross_in = (g0 >= 0) & (g1 < 0)
        t_cross = t + (t_exit - t) * g0 / jnp.where(cross_in, g0 - g1, 1.0)
        in_shell = (g0 < 0) & (g0 >= -tau)
        # A ray that *starts* inside a shell starts on a surface (a secondary ray): not a hit on itself.
        shell_hit = in_shell & deeper & front & (t > 1e-6 * tr.t_far)
        fine_hit = has & ((cross_in & front) | shell_hit)
        fine_unknown = (
            has
            & ~fine_hit
            & ((cross_in & ~front) | (g0 < -tau) | (in_shell & deeper & ~front & (t > 1e-6 * tr.t_far)))
        )
        at_fine = level == 0
        new_status = jnp.where(
            at_fine & fine_hit,
            jnp.int32(HIT),
            jnp.where(at_fine & fine_unknown, jnp.int32(UNKNOWN), jnp.int32(MISS)),
        )
        t_hit = jnp.where(cross_in, t_cross, t)

        advance = jnp.where(at_fine, new_status == MISS, skip)
        step_u = t_u <= t_v
        ij_adv = ij + jnp.where(
            step_u, jnp.array([0, 1], jnp.int32), jnp.array([1, 0], jnp.int32)
        ) * jnp.where(step_u, du[0], du[1]).astype(jnp.int32)
        # Where to go next: after an advance, hi-Z climbs one level; two-level climbs back to the coarse
        # level on leaving the coarse cell; on a possible hit, descend (hi-Z one level, two-level to 0).
        if cfg.hierarchy == "hiz":
            up = jnp.minimum(level + 1, top)
            down = jnp.maximum(level - 1, 0)
        elif cfg.hierarchy == "two_level":
            shift = jnp.int32(coarse)
            leaves = jnp.any(jnp.right_shift(ij_adv, shift) != jnp.right_shift(ij, shift))
            up = jnp.where((level == 0) & leaves & (coarse > 0), jnp.int32(coarse), level)
            down = jnp.int32(0)
        else:
            up = down = jnp.int32(0)
        ij_up = jnp.right_shift(ij_adv, up - level)
        ij_down = cell_at(t, down)
        ij_down = jnp.clip(
            ij_down, jnp.left_shift(ij, level - down), jnp.left_shift(ij + 1, level - down) - 1
        )

        t_new = jnp.where(advance, t_exit, jnp.where(new_status == HIT, t_hit, t))
        level_new = jnp.where(advance, up, jnp.where(at_fine, level, down))
        ij_new = jnp.where(advance, ij_up, jnp.where(at_fine, ij, ij_down))
        texel_new = jnp.where(new_status != MISS, jnp.stack([i0, j0]), texel)
        # Left the face (numerically) before tb: end the piece.
        out = jnp.any((ij_new < 0) | (ij_new >= jnp.right_shift(jnp.int32(res), level_new)))
        t_new = jnp.where(out & (new_status == MISS), tb, t_new)
        return new_status, t_new, steps + 1, texel_new, level_new, ij_new

    status, t, steps, texel = state
    start = jnp.maximum(t, ta)
    go = (status == MISS) & (span > 1e-6 * tr.t_far)
    seg_steps = steps + max_steps  # the step budget is per octant piece

    def cond(c):
        # No lax.cond around the loop: under vmap a batched predicate would batch every closed-over map.
        status, t, steps = c[0], c[1], c[2]
        return go & (status == MISS) & (t < tb) & (steps < seg_steps)

    init = (status, start, steps, texel, jnp.int32(top), cell_at(start, top))
    out = jax.lax.while_loop(cond, body, init)
    status, t, steps2, texel = out[0], out[1], out[2], out[3]
    # Running out of steps inside the piece is "unknown" (the ray is not known to be free beyond t).
    status = jnp.where(go & (status == MISS) & (t < tb) & (steps2 >= seg_steps), UNKNOWN, status)
    t = jnp.where(go, t, state[1])
    return status, t, steps2, texel


def trace_probe(
    tr: LightFieldTracer,
    p: Int[Array, ""],
    origin: Float[Array, "3"],
    direction: Float[Array, "3"],
    t_min: Float[Array, ""],
    t_max: Float[Array, ""],
) -> tuple[Int[Array, ""], Float[Array, ""], Int[Array, ""], Int[Array, "2"]]:
    """Single-probe trace of ONE ray over [t_min, t_max] (McGuire 2017 §4.1, Listing 1 ``singleProbeTrace``).

    Args:
        tr: the tracer.
        p: probe row.
        origin, direction: the ray, world frame; ``direction`` unit length.
        t_min, t_max: the segment to march.

    Returns:
        (status MISS=0 / HIT=1 / UNKNOWN=2, t of the hit or of the last point the probe saw free (t_max on
        a miss), texel steps, fine texel (row, col) of the hit or of the unknown).
    """
    o = origin - tr.pos_world[p]
    dt = o.dtype
    safe_d = jnp.where(jnp.abs(direction) > 1e-12, direction, 1e-12)
    tc = jnp.sort(jnp.clip(-o / safe_d, t_min, t_max))
    bounds = jnp.concatenate([t_min[None], tc, t_max[None]]).astype(dt)
    state = (jnp.int32(MISS), t_min, jnp.int32(0), jnp.zeros(2, jnp.int32))

    def seg(k, st):
        return _trace_segment(tr, p, o, direction, bounds[k], bounds[k + 1], st)

    status, t, steps, texel = jax.lax.fori_loop(0, 4, seg, state)
    t = jnp.where(status == MISS, t_max, t)
    return status, t, steps, texel


# ------------------------------------------------------------------------------------- many probes
def _next_probe(tr, origin, direction, t, visited, prev_probe, prev_cell, prev_slot):
    """Next probe for a ray whose unresolved part starts at t: (probe or -1, cell id, slot in the cage)."""
    x = origin + t * direction

    def line_dist2(ids):
        rel = tr.pos_world[jnp.maximum(ids, 0)] - origin[None, :]
        along = rel @ direction
        return jnp.where(ids >= 0, jnp.sum(rel * rel, axis=-1) - along * along, jnp.inf)

    if isinstance(tr.index, GridIndex):
        ids, cell = tr.index.cage(x)
        # McGuire §4.1: start with the probe nearest the ray's line; in the same cage, (i+3) mod 8.
        d2 = line_dist2(ids)
        first = jnp.where(
            (cell == prev_cell) & (prev_probe >= 0), (prev_slot + 3) % 8, jnp.argmin(d2).astype(jnp.int32)
        )
        slots = (first + 3 * jnp.arange(8, dtype=jnp.int32)) % 8
        cand = ids[slots]
    else:
        # Wang §4.1: the voxel's candidates (visible, ranked when the index was built); among those still
        # untried, take the one nearest the ray's line, McGuire's criterion for the shortest polyline —
        # the runtime, ray-dependent part of the ranking.
        cand, cell = tr.index.lookup(x)
        slots = jnp.arange(cand.shape[0], dtype=jnp.int32)
    ok = (cand >= 0) & ~jnp.any(cand[:, None] == visited[None, :], axis=1)
    ok = ok & tr.usable[jnp.maximum(cand, 0)]
    if isinstance(tr.index, GridIndex):
        k = jnp.argmax(ok).astype(jnp.int32)
    else:
        k = jnp.argmin(jnp.where(ok, line_dist2(cand), jnp.inf)).astype(jnp.int32)
    found = ok[k]
    probe = jnp.where(found, cand[k], -1)
    if isinstance(tr.index, VoxelIndex):
        # The voxel's candidates are judged from the voxel, not from this ray's point: when all are spent,
        # fall back to the untried usable probe nearest the point (any probe set, O(n_probes)).
        every = jnp.arange(tr.pos_world.shape[0], dtype=jnp.int32)
        free = tr.usable & ~jnp.any(every[:, None] == visited[None, :], axis=1)
        dist2 = jnp.sum((tr.pos_world - x[None, :]) ** 2, axis=-1)
        j = jnp.argmin(jnp.where(free, dist2, jnp.inf)).astype(jnp.int32)
        probe = jnp.where(found, probe, jnp.where(free[j], j, -1))
    return probe, cell, slots[k]


def trace_ray(
    tr: LightFieldTracer,
    origin: Float[Array, "3"],
    direction: Float[Array, "3"],
    t_max: Float[Array, ""],
) -> tuple[Int[Array, ""], Float[Array, ""], Int[Array, ""], Int[Array, "2"], Int[Array, ""], Int[Array, ""]]:
    """Light-field trace of ONE ray through the probe set (McGuire 2017 Listing 1 ``lightFieldTrace``).

    Returns:
        (status RAY_MISS / RAY_HIT / RAY_UNRESOLVED, t (inf on a miss; last free point if unresolved),
        probe, texel, texel steps, probes tried).
    """
    n_max = tr.config.max_probes
    # Exit from the scene's box (slab test): beyond it the ray is known to be free.
    safe_d = jnp.where(jnp.abs(direction) > 1e-12, direction, 1e-12)
    t_box = jnp.min(jnp.maximum((tr.bounds[0] - origin) / safe_d, (tr.bounds[1] - origin) / safe_d))
    t_end = jnp.clip(jnp.minimum(t_max, t_box), 0.0, tr.t_far).astype(origin.dtype)

    def cond(c):
        return c[0] == UNKNOWN

    def body(c):
        _, t, visited, n, prev_p, prev_cell, prev_slot, steps, _, _ = c
        p, cell, slot = _next_probe(tr, origin, direction, t, visited, prev_p, prev_cell, prev_slot)
        found = (p >= 0) & (n < n_max)
        st, t2, s2, texel = trace_probe(tr, jnp.maximum(p, 0), origin, direction, t, t_end)
        st = jnp.where(found, st, -1)  # -1: nothing left to try
        t2 = jnp.where(found & (st == UNKNOWN), jnp.maximum(t2, t), jnp.where(found, t2, t))
        visited = visited.at[jnp.minimum(n, n_max - 1)].set(jnp.where(found, p, visited[n_max - 1]))
        return (
            st,
            t2,
            visited,
            n + found.astype(jnp.int32),
            p,
            cell,
            slot,
            steps + jnp.where(found, s2, 0),
            p,
            texel,
        )

    init = (
        jnp.int32(UNKNOWN),
        jnp.zeros((), origin.dtype),
        -jnp.ones(n_max, jnp.int32),
        jnp.int32(0),
        jnp.int32(-1),
        jnp.int32(-1),
        jnp.int32(0),
        jnp.int32(0),
        jnp.int32(-1),
        jnp.zeros(2, jnp.int32),
    )
    st, t, _, n, _, _, _, steps, p, texel = jax.lax.while_loop(cond, body, init)
    status = jnp.where(
        st == HIT, jnp.int32(RAY_HIT), jnp.where(st == MISS, jnp.int32(RAY_MISS), jnp.int32(RAY_UNRESOLVED))
    )
    t = jnp.where(status == RAY_MISS, jnp.inf, t)
    return status, t, jnp.where(status == RAY_HIT, p, -1), texel, steps, n


@eqx.filter_jit
def trace_light_field(
    tr: LightFieldTracer,
    origins: Float[Array, "n_rays 3"],
    directions: Float[Array, "n_rays 3"],
    t_max: Float[Array, " n_rays"] | None = None,
    *,
    chunk: int | None = None,
) -> TraceResult:
    """Trace a batch of rays through the light-field probes (jitted; one compile per tracer layout).

    Args:
        tr: from :func:`make_tracer`.
        origins: ray origins, world frame (offset secondary rays off their surface yourself).
        directions: unit directions.
        t_max: optional per-ray maximum distance (default: the scene diagonal).
        chunk: trace this many rays at a time (``lax.map``), so working memory stays bounded as the
            batch grows; ``None`` traces all rays at once (static: one compile per value).

    Returns:
        A :class:`TraceResult`; unresolved rays are flagged, never counted as hits or misses.
    """
    dt = tr.pos_world.dtype
    origins = jnp.asarray(origins, dt)
    directions = jnp.asarray(directions, dt)
    if t_max is None:
        t_max = jnp.full(origins.shape[:1], jnp.inf, dt)
    t_max = jnp.asarray(t_max, dt)
    if chunk is None:
        out = jax.vmap(trace_ray, in_axes=(None, 0, 0, 0))(tr, origins, directions, t_max)
    else:
        out = jax.lax.map(lambda x: trace_ray(tr, *x), (origins, directions, t_max), batch_size=chunk)
    return TraceResult(*out)
