"""Light-field probe ray tracing (McGuire et al. 2017 §4; hi-Z variant of Wang et al. 2019 §4.2).

**Single probe.** A ray segment seen from a probe splits at the three coordinate planes through the probe
into ≤ 4 pieces, one per octant; on each octant face the octahedral map is a central projection followed
by an affine fold, so each piece projects to a *straight* 2D segment (McGuire §4.1, "a line segment maps
to a polyline with at most four segments"). Every grid line u = c on the face is the plane
(a_u − c·s)·q = 0 through the probe (s the octant's signs, a_u the face's numerator), so the ray parameter
where the march enters or leaves a cell is the root of a *linear* equation: the march steps exactly from
cell to cell in ray distance t (a DDA, Amanatides & Woo 1987), never in approximate 2D steps.

**Cells and surfels.** The march runs over the *geometry* maps (distance and normal; their resolution R
need not be the radiance maps'), ``subdivide`` × ``subdivide`` cells per texel (``_surfels``). Each texel
is a surfel (McGuire §4.1: "a planar patch at distance r with normal n"): the plane through x = r·ω_c with
the baked normal, *turned toward the probe* — front and back are judged from the side the probe observes
(McGuire: "using the observed normal"), so a one-sided sheet seen from behind is a surface like any
other, whatever the bake stored. Within a cell's cone the ray is *in front* of the surfel (on the
probe's side of its plane), *crosses* it, or is *behind* it. A crossing is a hit at the exact plane
crossing; a ray behind the surfel by more than the surface *thickness* has entered space the probe cannot
see → unknown, stopping at the cell's entry (the last point the probe saw in free space). Inside the
thickness shell a ray moving deeper is a hit, one moving out continues (a surfel is only a planar
approximation of a curved surface). A ray whose origin lies in a surfel's shell behind its plane, or
in front of it within the plane's own error (``start_tol``), starts on that surface (a secondary ray):
it is not a hit on it. A cell where the texel's surfel and a neighbour's are not one
surface (a silhouette, ``_surfels``) is *ambiguous*: only "in front of every candidate surfel" passes;
anything else is unknown, for another probe to decide. A one-surface cell whose surfel meets a neighbour's
in a *concave crease* (a room's corner) is bounded by both planes: in front of both is free, its own plane
crossed first is a hit, the neighbour's is unknown (``_march._partners``); with one plane a ray slips
behind the floor near a corner.
A probe's miss counts only if the probe sees where the ray's trace ends (``_after_probe``).

**Hierarchy.** Every cell has a conservative lower bound of its candidate surfels' radial distance over
its cone (min-MIPped) and an upper bound beyond which a point is deep behind them (max-MIPped; Wang 2019
§4.2 uses both). If the ray's largest radial distance over a cell's t-interval (the ray's distance from
the probe is convex in t, so the larger end value) is below the cell's lower bound, every fine cell below
would say "in front": the cell is skipped whole. If the ray where it enters a cell is beyond the upper
bound, every fine cell would say "unknown" there: the trace ends at once. ``two_level`` is McGuire's
scheme (a coarse level at 1/16 the resolution per axis, then the fine level inside each coarse cell that
may hold a hit); ``hiz`` is Wang's full hierarchy (Uludag 2014 hi-Z: on a possible hit go one level finer;
after a skip go one level coarser once the ray leaves the parent cell — inside it the parent is known to
fail), capped below the coarsest levels ("we conservatively avoid the coarsest levels"); it starts at the
level where the piece spans a cell or two, and while still at the trace's start (on a surface, or next to
the one that stopped the previous probe) it descends straight to the finest level. ``flat`` marches every
fine cell (the reference for the tests). All three give the same answers.

**Many probes.** McGuire's Listing 1: trace one probe; on *unknown* advance the ray's start to the point
reached and try the next probe. Uniform grids: the cage of eight probes around the current point, starting
with the probe nearest the ray's line, then (i+3) mod 8 while the point stays in the same cage (§4.1).
Other sets: the ranked candidates of the voxel containing the current point (Wang §4.1). When the index
has no untried candidate left (or its share of ``max_probes`` is spent), the ray continues in the untried
usable probes nearest the last free point x that *see* x (x closer than the probe's distance map in x's
direction, with a margin), up to ``fallback_probes`` of them. A ray tries at most ``max_probes`` distinct
probes and never revisits one; if no probe resolves it, it is *unresolved* (counted by the callers,
never passed off as a hit or miss).

**Engines.** :func:`trace_ray` is the per-ray engine (vmapped nested loops; the reference). ``_wavefront``
runs the same steps (``_march._march_step`` and the helpers below) as a state machine over a batch of
lanes that are refilled as rays finish; ``_engine.trace_light_field`` chooses by ``TraceConfig.engine``.
Status codes: ``_status.TraceStatus``.
"""

from __future__ import annotations

import dataclasses
import math
from functools import partial
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int, Shaped, UInt8, UInt16
from scipy.spatial import cKDTree

from ..._core import (
    ConfigError,
    LightFieldProbes,
    add_border,
    check_memory,
    dot3,
    oct_encode,
    texel_directions,
    unpack_normal,
)
from ..._core.runtime import check_settings, progress_bar, setting
from .._bake import _warn_probe_layout, padded_capacity
from ._index import GridIndex, VoxelIndex, grid_index, nearest_index, voxel_index
from ._march import _candidates, _partners, trace_probe
from ._status import TraceStatus
from ._surfels import cell_cones, interleave_quadrants, neighbour_pairs, probe_cells_quadrants

_FALLBACK_POOL = 32  # nearest probes a fallback pick tests (per voxel of ``nearest_index``)
HIERARCHIES = ("hiz", "two_level", "flat")
ENGINES = ("per_ray", "wavefront")


@dataclasses.dataclass(frozen=True, kw_only=True)
class TraceConfig:
    """Light-field tracer settings.

    Attributes:
        hierarchy: ``"hiz"`` (Wang 2019 §4.2), ``"two_level"`` (McGuire 2017 §4.2) or ``"flat"``.
        coarse_factor: two-level: the coarse level is this many times coarser per axis (McGuire: 16).
        hiz_skip_top: hi-Z: how many of the coarsest MIP levels never to use (Wang: "avoid the coarsest").
        thickness: surface thickness as a fraction of the surfel's radial distance (McGuire's
            ``minThickness``/``maxThickness`` scale with distance the same way). 1.5 % since 2026-12-05
            (was 3 %), with ``surface_lookback``: a thinner shell makes fewer hits on the wrong surface
            (agreement with exact casting up) and leaves more rays unknown, which the look-back takes
            up. On Sponza's 16×8×8 grid at 512² (``benchmarks/convergence.py``, CameraMain's glossy
            rays): agreement 0.942 → 0.960, unresolved among rays whose origin a probe sees 9.1 → 7.1 %
            (3 % with the look-back: 0.935 and 6.0 %).
        start_tol: a ray starts on a surfel's surface — its plane is not taken for a hit, the ray is
            leaving it (a secondary ray) — when its origin lies behind the plane by at most the thickness
            or in front of it by at most this fraction of the surfel's distance (the plane's own error
            where the origin lies: bfloat16 normals, a texel's width of curvature). A secondary ray never
            enters the surface it leaves, so a plane the origin lies clearly in front of is another
            surface: a ray leaving a floor 14 cm from a wall crosses the wall's plane, a hit. Until
            2026-12-04 (results version 2) the thickness counted in front too: such rays passed through the
            wall (to a far hit, or unknown); on Sponza at 512² (CameraMain's glossy rays) this took the
            hits agreeing with exact casting from 0.922 to 0.942 (16×8×8) and 0.928 to 0.954 (8×4×4), and
            the unresolved rays among those whose origin a probe sees from 10.2 % to 9.1 %.
        subdivide: march cells per geometry texel and axis: 2 (a cell per quarter texel, so only the
            half-texel next to a silhouette is ambiguous) or 1.
        edge_tol: relative tolerance of the one-surface test between neighbouring surfels (``_surfels``);
            ``None`` turns the test off (every cell is its texel's surfel, McGuire's model).
        edge_on_deg: a crossing of a cell's own surfel plane (or, in an ambiguous cell, of every candidate's)
            is unknown, not a hit — another probe decides — where its radial distance differs from the
            surfel's by more than a plane seen at this angle from its normal could make it within the cell:
            tan θ × 0.7 texel widths (the farthest a march cell's point lies from its texel's centre), i.e.
            5 % at 512² and θ = 84.5°. There the texel's one plane stands for geometry it does not fit. On
            Sponza's 8×4×4 grid at 512² (seed 2), it turned 95 of the 154 resolved hits short of the exact
            one by more than 2 % — most of them in the probe's own free space (its exact ray in that
            direction met the surface farther) — into rays other probes resolved: agreement 0.891 → 0.924.
            In an ambiguous cell every met candidate counts (until 2026-12-04 only the cell's own surfel:
            a ray starting on a floor crossed a nearer column's extended plane 1 m behind that column and
            took it for a hit). ``None``: off.
        max_probes: distinct probes a ray may try in all (McGuire: the 8 of a cage).
        fallback_probes: of those, how many may come from the search for probes that see the last free
            point, after the index's candidates (0: none). The index gets the rest (at least one).
        fallback_radius: fallback probes lie within this many probe spacings (the median distance from a
            usable probe to its nearest neighbour) of the point.
        fallback_margin: a probe sees a point when the point lies in front of the probe's surfel(s) in its
            direction by this fraction of their distance.
        surface_lookback: the fallback also takes up a ray stalled *on* a surface: a probe qualifies when
            the last free point x lies on its surfel — in front of the plane or behind it within the
            thickness, the tracer's own surface — and the probe sees the ray this fraction of x's
            distance along it earlier, in free space, the way it came (``None``: off, x must be in front).
            The probe's march then takes x, in the shell and moving deeper, for a hit. Without it such a
            ray stays unresolved: the probe that carried it there stopped at the cell entry in front of
            the surface, and x lies within the planes' own error of it (a median 2 cm short of the exact
            hit on Sponza), so no probe sees x strictly in front. The look-back refuses rays that an
            earlier probe let *through* a surface: their stall point lies behind it, and so does the
            point before it. On Sponza's 16×8×8 grid at 512² (8000 shading rays from CameraMain's
            surfaces, thickness 3 %): unresolved 6.45 → 4.89 %, hits agreeing with exact casting
            0.962 → 0.958; with no look-back (x on the surfel suffices) 3.93 % and 0.951, half the new
            hits wrong; 0.02 and 0.1 lie either side (5.17 % / 0.959 and 4.70 % / 0.957). With the 1.5 %
            thickness: 5.44 % and 0.971 (7.06 % and 0.974 without the look-back).
        max_steps: steps per octant piece of a single-probe trace (``None``: 6 × the march resolution).
        bounds_margin: rays stop this far (fraction of the largest scene extent) outside the scene box.
        engine: how :func:`trace_light_field` runs the rays: ``"per_ray"`` (one ray per vmapped lane,
            nested loops) or ``"wavefront"`` (``_wavefront``: a state machine per lane, finished lanes
            refilled; the same answers, t to a few float32 ulps). Both are held to the standalone NumPy
            reference (``_simple.trace_probe_simple``).
        wavefront_lanes: wavefront: rays in flight at once (the batch; also bounds working memory).
            1024 lanes and 4 steps: the fastest, or within timing noise of it, on both the Cornell box and
            Sponza among 512 / 1024 / 2048 lanes and 2 / 4 / 8 / 16 steps (8000 rays, 2 CPU cores).
        wavefront_steps: wavefront: steps between refills of finished lanes (a finished lane idles until
            then).
    """

    hierarchy: str = setting("hiz", choices=HIERARCHIES)
    coarse_factor: int = setting(16, lo=2)  # and a power of two (__post_init__)
    hiz_skip_top: int = setting(1, lo=0)
    thickness: float = setting(0.015, lo=0.0, hi=1.0, hi_open=True)
    start_tol: float = setting(1e-3, lo=0.0, hi=1.0, hi_open=True)
    subdivide: int = setting(2, choices=(1, 2))
    edge_tol: float | None = setting(0.05, lo=0.0, lo_open=True)
    edge_on_deg: float | None = setting(84.5, lo=0.0, hi=90.0, lo_open=True, hi_open=True)
    max_probes: int = setting(16, lo=1)
    fallback_probes: int = setting(8, lo=0)
    fallback_margin: float = setting(0.0, lo=0.0, hi=1.0, hi_open=True)
    fallback_radius: float = setting(2.5, lo=0.0, lo_open=True)
    surface_lookback: float | None = setting(0.05, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    max_steps: int | None = setting(None, lo=1)
    bounds_margin: float = setting(0.05, lo=0.0)
    engine: str = setting("per_ray", choices=ENGINES)
    wavefront_lanes: int = setting(1024, lo=1)
    wavefront_steps: int = setting(4, lo=1)

    def __post_init__(self):
        """The declared ranges and choices (``_core.runtime.check_settings``), then what is not a range."""
        check_settings(self)
        if self.coarse_factor & (self.coarse_factor - 1):
            raise ConfigError(
                f"TraceConfig.coarse_factor must be a power of two ≥ 2, got {self.coarse_factor}"
            )

    @property
    def index_probes(self) -> int:
        """Probes a ray may take from the index before the fallback search."""
        return max(self.max_probes - self.fallback_probes, 1)


class LightFieldTracer(eqx.Module):
    """Everything the tracer reads, precomputed from :class:`LightFieldProbes` (build with
    :func:`make_tracer`).

    Attributes:
        pos_world: probe centres.
        usable: probes the tracer may use (active, not inside geometry).
        row: each probe's row in the per-probe maps below, which hold the usable probes only, in
            :func:`tracer_rows` rows (the rows after them are zeros); an unusable probe's row is 0 and
            never read.
        surfel_r: per geometry texel, *bordered* ((R+2)², the octahedral neighbours across the fold in
            the ring), the surfel's radial distance r, 0 where the texel's ray hit nothing (its has-surface
            flag: a surfel is never at the probe's centre, see :func:`_probe_cells`); its point is r·ω_c
            (:meth:`surfels`).
        texel_dirs: the bordered texels' sample directions ω_c, shared by every probe.
        surfel_n: the surfel's normal, turned toward the probe (bordered), bfloat16 (half the bytes; a
            normal tilts by < 4e-3 rad, and the bounds are built from the rounded normals). bfloat16, not
            float16: XLA:CPU converts float16 with library calls it cannot link on a CPU without F16C
            (``--xla_cpu_max_isa=SSE4_2``: "Symbols not found: __extendhfsf2"), bfloat16 with bit operations.
            Held as the values' uint16 bits (:func:`_bf16_bits`; read through :meth:`surfels`).
        ambiguous_bits: per march cell, the texel's surfel is not the only surface there (``_surfels``),
            eight cells of a row to a byte (:meth:`is_ambiguous`).
        bound_flat: per probe, the conservative lower bounds of MIP levels 1 ((M/2)²) … top, flattened
            (M = ``march_res``; min-MIP), as one-byte codes of :attr:`bound_table`, rounded down
            (:meth:`lower`). Level 0, the march cells, is not stored: there the fine test reads the
            surfels themselves (``_march._march_step``).
        upper_flat: likewise the upper bounds beyond which the fine test says unknown (max-MIP), rounded
            up (:meth:`upper`). Issue 33: 18.8 → 9.5 MB a usable probe at 512², ``subdivide`` 2, with
            bfloat16 bounds; 5.6 MB with the one-byte codes, the flags as bits and the has-surface flag in
            ``surfel_r``; 3.5 MB without level 0 (2.8 MB at ``subdivide`` 1). A looser bound only costs a
            step, never another answer.
        bound_table: the 256 distances the bound codes stand for (:func:`bound_table`): 0, then
            ``far``·2^(2 − (255 − q)/21), 21 codes an octave (steps of 3.4 %) up to 4·``far``.
        spacing: the probes' typical spacing (median nearest-neighbour distance of the usable probes).
        far: distance stored for escaping rays.
        t_far: largest ray distance traced (the scene bounds' diagonal).
        bounds: the scene's (min, max) corners, inflated by ``bounds_margin``; nothing lies outside, so a
            ray is traced only until it leaves them (Wang 2019 §5: visibility is bounded by the scene
            bounds). The margin lets a ray that slips through a wall inside one texel (whose surfel is
            another surface) go on to be *behind* that wall, hence unknown, rather than a false miss.
        index: the probe-selection index.
        near: each voxel's nearest usable probes, for the fallback search (:func:`nearest_index`).
        res: interior geometry-map resolution R (static).
        config: settings (static).
    """

    pos_world: Float[Array, "n_probes 3"]
    usable: Bool[Array, " n_probes"]
    row: Int[Array, " n_probes"]
    surfel_r: Float[Array, "n_rows rb rb"]
    texel_dirs: Float[Array, "rb rb 3"]
    surfel_n: UInt16[Array, "n_rows rb rb 3"]
    ambiguous_bits: UInt8[Array, "n_rows m m8"]
    bound_flat: UInt8[Array, "n_rows k"]
    upper_flat: UInt8[Array, "n_rows k"]
    bound_table: Float[Array, " 256"]
    spacing: Float[Array, ""]
    far: Float[Array, ""]
    t_far: Float[Array, ""]
    bounds: Float[Array, "2 3"]
    index: GridIndex | VoxelIndex
    near: VoxelIndex
    res: int = eqx.field(static=True)
    config: TraceConfig = eqx.field(static=True)

    @property
    def sub(self) -> int:
        return self.config.subdivide

    @property
    def march_res(self) -> int:
        """Cells per axis of the finest march level (``subdivide`` × the geometry resolution)."""
        return self.res * self.config.subdivide

    @property
    def n_levels(self) -> int:
        return int(math.log2(self.march_res)) + 1

    def level_offset(self, level: int) -> int:
        """Where MIP level ``level`` ≥ 1 starts in :attr:`bound_flat` / :attr:`upper_flat` (level 0, the
        march cells themselves, is not stored: :func:`_cell_maps`)."""
        return sum((self.march_res >> k) ** 2 for k in range(1, level))

    def surfels(self, w, rows, cols) -> tuple[Array, Array, Array]:
        """(points r·ω_c, normals, has-surface) of the bordered texels (rows, cols) of map row ``w``, in
        float32: the same points as r·ω_c computed at build time (one float32 product)."""
        r = self.surfel_r[w, rows, cols]
        n = _from_bf16_bits(self.surfel_n[w, rows, cols])
        return r[..., None] * self.texel_dirs[rows, cols], n, r > 0

    def is_ambiguous(self, w, i, j) -> Array:
        """Whether march cell (i, j) of map row ``w`` is ambiguous (its bit in ``ambiguous_bits``)."""
        byte = self.ambiguous_bits[w, i, jnp.right_shift(j, 3)]
        return (jnp.right_shift(byte, jnp.bitwise_and(j, 7).astype(jnp.uint8)) & 1) == 1

    def lower(self, w, flat) -> Array:
        """Lower bound of MIP entry ``flat`` of map row ``w`` (float32; never above the exact bound): a
        table entry, no arithmetic, so both tracers and the build read the same value."""
        return self.bound_table[self.bound_flat[w, flat]]

    def upper(self, w, flat) -> Array:
        """Upper bound of MIP entry ``flat`` of map row ``w`` (float32; never below the exact bound)."""
        return self.bound_table[self.upper_flat[w, flat]]


class TraceResult(eqx.Module):
    """Per ray: status (0 miss, 1 hit, 2 unresolved), hit distance (inf unless hit; for unresolved rays
    the last point known to be free), probe and geometry-map texel (row, col) that resolved the hit (for
    an unresolved ray the texel where the last probe tried gave up; (0, 0) on a miss), march steps,
    probes tried, and how many of those came from the fallback search."""

    status: Int[Array, " n_rays"]
    t: Float[Array, " n_rays"]
    probe: Int[Array, " n_rays"]
    texel: Int[Array, "n_rays 2"]
    steps: Int[Array, " n_rays"]
    probes_tried: Int[Array, " n_rays"]
    fallback: Int[Array, " n_rays"]

    @property
    def hit(self) -> Bool[Array, " n_rays"]:
        return self.status == TraceStatus.HIT

    @property
    def unresolved(self) -> Bool[Array, " n_rays"]:
        return self.status == TraceStatus.UNRESOLVED


# --------------------------------------------------------------------------------------------- building
def _geometry_maps(distance, normal, far):
    """Bordered (R+2)² geometry maps of all probes (a bake's ``distance``, ``normal``, ``far``): surfel
    points, normals turned toward the probe, has-surface flags, and the sample directions (border texels:
    their source texel's direction)."""
    res = distance.shape[-1] - 2
    far = jnp.asarray(far, jnp.float32)
    dist = jnp.asarray(distance, jnp.float32)
    nrm = jnp.asarray(normal, jnp.float32)
    omega = add_border(texel_directions(res, jnp.float32))
    has = (dist < 0.999 * far) & (dot3(nrm, nrm) > 0.25)
    facing = dot3(nrm, omega[None])
    # Turn every normal toward the probe (front and back are judged from the observed side, whatever the
    # bake stored); one missing or perpendicular to the view gets the view-facing normal.
    nrm = jnp.where((facing > 0)[..., None], -nrm, nrm)
    nrm = jnp.where(((jnp.abs(facing) > 1e-3) & has)[..., None], nrm, -omega[None])
    x = jnp.where(has[..., None], dist[..., None] * omega[None], 0.0)
    return x, nrm, has, omega


def _mip_flat(level: Shaped[Array, "p m m"], how: str) -> Shaped[Array, "p k"]:
    """All levels m², (m/2)², …, 1 of a min- or max-MIP chain, flattened per probe (any ordered dtype:
    the bounds' float32 values or their codes)."""
    levels = [level.reshape(level.shape[0], -1)]
    while level.shape[1] > 1:
        p, r = level.shape[0], level.shape[1]
        level = level.reshape(p, r // 2, 2, r // 2, 2)
        level = level.min(axis=(2, 4)) if how == "min" else level.max(axis=(2, 4))
        levels.append(level.reshape(p, -1))
    return jnp.concatenate(levels, axis=1)


@jax.jit
def _probe_surfels(distance, normal16, far):
    """ONE probe's bordered surfels from its baked maps (normals packed, ``_core.pack_normal``): points,
    normals as the march reads them, has-surface flags, sample directions (:func:`_geometry_maps`). A
    program of its own: fused into the one-surface tests that read them, they were computed again for
    each (30 ms a probe at 512², 7 + 10 ms apart)."""
    normal = unpack_normal(normal16, distance >= far)
    xb, nb, hb, wb = _geometry_maps(distance[None], normal[None], far)
    # The march reads bfloat16 normals (LightFieldTracer.surfel_n): bound the planes it will test.
    nb = nb.astype(jnp.bfloat16).astype(jnp.float32)
    return xb[0], nb[0], hb[0], wb


@partial(jax.jit, static_argnames=("tol",))
def _probe_pairs(surfels, *, tol: float | None):
    """ONE probe's one-surface tests of neighbouring texels (``_surfels.neighbour_pairs``, which says why
    this is a program of its own) from its :func:`_probe_surfels`."""
    return neighbour_pairs(*surfels, tol)


@partial(jax.jit, static_argnames=("sub", "thickness"))
def _probe_cells(distance, surfels, pairs, far, cones_cells, cones_texels, *, sub: int, thickness: float):
    """ONE probe's bordered surfel distances (0: no surface) and normals, and its march cells' (lower
    bound, upper bound, ambiguous) per cell quadrant (``_surfels.probe_cells_quadrants``), from its
    :func:`_probe_surfels` and :func:`_probe_pairs`. The cells' and texels' cones
    (``_surfels.cell_cones``) are arguments, computed once per resolution for all probes."""
    xb, nb, hb, wb = surfels
    big = 4.0 * jnp.asarray(far, jnp.float32)
    cells = probe_cells_quadrants(
        xb, nb, hb, pairs, cones_cells, cones_texels, sub=sub, thickness=thickness, big=big
    )
    # Stored compactly (LightFieldTracer): the radial distance, not the point, 0 for no surface (a hit at
    # the probe's centre, never baked, would read as none: kept above 0); bfloat16 normals.
    dist = jnp.maximum(jnp.asarray(distance, jnp.float32), jnp.finfo(jnp.float32).tiny)
    radial = jnp.where(hb, dist, 0.0)
    return radial, _bf16_bits(nb), cells, wb


def _bf16_bits(x):
    """bfloat16 values (or float32 rounded to them) as their uint16 bits, the tracer's storage: XLA:CPU
    updates a bfloat16 buffer in place by converting all of it to float32 and back (0.16 s a 512² row:
    stacking 128 probes took 108 s instead of 9), an integer buffer in place."""
    return jax.lax.bitcast_convert_type(x.astype(jnp.bfloat16), jnp.uint16)


def _from_bf16_bits(bits):
    """float32 values of :func:`_bf16_bits`."""
    return jax.lax.bitcast_convert_type(bits, jnp.bfloat16).astype(jnp.float32)


#: Bound codes an octave (:func:`bound_table`): steps of 2^(1/21) = 3.4 % between codes.
_BOUND_CODES_PER_OCTAVE = 21


def bound_table(far) -> Float[Array, " 256"]:
    """The distances the tracer's one-byte bound codes stand for: code 0 is 0, code q ≥ 1 is
    ``far``·2^(2 − (255 − q)/21), from 9e-4·``far`` to 4·``far`` (the bounds' cap, ``_surfels``'
    ``big``). Bounds are rounded outward to them (:func:`_bound_codes`), as Wang 2019 §5.3 stores its
    min/max depth MIPs at reduced precision (RG16F); one byte here, the codes' 3.4 % steps only cost steps."""
    q = np.arange(256, dtype=np.float64)
    frac = np.where(q > 0, 2.0 ** (2.0 - (255.0 - q) / _BOUND_CODES_PER_OCTAVE), 0.0).astype(np.float32)
    return jnp.asarray(frac * np.float32(far))  # on the host: no compiled program for 256 products


def _bound_codes(v, table, down: bool):
    """Codes of ``table`` (:func:`bound_table`) for the values ``v`` that never cross them: an entry ≤ v
    (``down``: a lower bound) or ≥ v (an upper bound; ``v`` ≤ the table's top, the surfels' ``big``). The
    code is the table's closed form rounded outward, then checked against the table itself and moved one
    step further out if it crossed (float32 log2 and the table's rounding are off by < 1e-4 of a code):
    exact on the safe side, the nearest code but now and then for a value within 1e-4 of a code of an
    entry. One gather a value (a search took ~35 s of ``make_tracer`` for 128 probes at 512²)."""
    est = jnp.log2(jnp.maximum(v, jnp.finfo(jnp.float32).tiny) / table[255]) * _BOUND_CODES_PER_OCTAVE + 255
    if down:
        q = jnp.clip(jnp.floor(est), 0.0, 255.0).astype(jnp.int32)
        q = jnp.where(table[q] > v, q - 1, q)
    else:
        q = jnp.clip(jnp.ceil(est), 0.0, 255.0).astype(jnp.int32)
        q = jnp.where(table[q] < v, q + 1, q)
    return jnp.clip(q, 0, 255).astype(jnp.uint8)


def _pack_bits(flags: Bool[Array, "m m"]) -> UInt8[Array, "m m8"]:
    """Rows of flags as bytes, eight columns to a byte, column j in bit j mod 8 of byte j // 8."""
    m = flags.shape[1]
    pad = -m % 8
    f = jnp.pad(flags, ((0, 0), (0, pad))).reshape(flags.shape[0], -1, 8).astype(jnp.uint8)
    return jnp.sum(jnp.left_shift(f, jnp.arange(8, dtype=jnp.uint8)[None, None, :]), axis=-1, dtype=jnp.uint8)


@jax.jit
def _cell_maps(lower_q, upper_q, ambiguous_q, table):
    """The quadrant lists of :func:`_probe_cells` as the (m, m) ambiguous cells' bits and the flattened
    min-MIP of the lower bounds and max-MIP of the upper bounds (codes of ``table``, rounded outward),
    levels 1 … top: a program of its own, so that the interleave copies materialised arrays
    (``_surfels.interleave_quadrants``).

    Level 0 is dropped (issue 33: 2.1 of the 5.6 MB a probe at 512², ``subdivide`` 2): the march never reads
    a finest cell's lower bound (there it runs the fine test, it does not skip), and a ray beyond a
    finest cell's upper bound is deep behind one of its candidate surfels, which the fine test reads and
    calls unknown itself (``_march._surfel_test``)."""
    lower, upper, ambiguous = (interleave_quadrants(a) for a in (lower_q, upper_q, ambiguous_q))
    # Coded before the MIP: rounding outward is monotone, so the min (max) of codes is the code of the min
    # (max), and only the finest level is coded.
    finest = lower.size
    lo = _mip_flat(_bound_codes(lower, table, down=True)[None], "min")[0, finest:]
    hi = _mip_flat(_bound_codes(upper, table, down=False)[None], "max")[0, finest:]
    return _pack_bits(ambiguous), lo, hi


def _probe_maps(
    distance, normal16, far, cones_cells, cones_texels, table, *, sub: int, tol: float, thickness: float
):
    """ONE probe's tracer arrays from its baked maps (four compiled programs; issue 32: eagerly, the
    set-up was ~200 small programs; one probe at a time, so any probe count reuses them): bordered surfel
    distances, normals, the ambiguous cells' bits, and the bound pyramids' codes
    (:class:`LightFieldTracer`'s layout, the bounds as codes of ``table``); last, the bordered texel
    directions (the same for every probe)."""
    surfels = _probe_surfels(distance, normal16, far)
    pairs = _probe_pairs(surfels, tol=tol)
    rb, nb, cells, directions = _probe_cells(
        distance, surfels, pairs, far, cones_cells, cones_texels, sub=sub, thickness=thickness
    )
    return rb, nb, *_cell_maps(*cells, table), directions


def tracer_bytes(n_rows: int, res: int, subdivide: int) -> int:
    """Bytes of a tracer's per-probe maps (:class:`LightFieldTracer`) in ``n_rows`` rows (a usable probe a
    row, padded to :func:`tracer_rows`) at geometry resolution ``res``: bordered surfel distances (float32)
    and normals (bfloat16 × 3), the ambiguous cells' bits and the lower- and upper-bound pyramids (a byte a
    code, levels 1 … top) of the ``res·subdivide``² march cells. 3.5 MB a row at 512², ``subdivide`` 2;
    2.8 MB at ``subdivide`` 1 (the shared texel directions, 3 MB once, are not counted)."""
    rb, m = res + 2, res * subdivide
    levels = sum((m >> k) ** 2 for k in range(1, m.bit_length()))  # level 0 is not stored
    return int(n_rows) * (rb * rb * (4 + 3 * 2) + m * -(-m // 8) + 2 * levels)


def tracer_rows(n_usable: int) -> int:
    """Rows of a tracer's per-probe maps for ``n_usable`` usable probes: the bake's probe-count bucket
    (:func:`~probeplace.probes.padded_capacity`; the rows past the usable probes are zeros, never read).
    A set's usable count varies with its seed and method; rows in a few buckets let the tracer's programs
    (the glossy shading's 8 s among them) compile once for all of them, not once per count."""
    return padded_capacity(n_usable)


def check_tracer_memory(n_usable: int, res: int, subdivide: int, counted: str = "usable probes") -> None:
    """Refuse a light-field tracer whose maps (:func:`tracer_bytes` of :func:`tracer_rows`) cannot fit
    (``_core.check_memory``): in :func:`make_tracer`, and in the runner before the bake with the probes
    placed (usable ≤ placed), so a set too large to trace is refused before minutes of baking.

    Twice the maps, as when they were staged on the host and copied to JAX; they are now stacked in place
    on the device (the peak is the maps plus one probe's working arrays), and the factor is kept as the
    margin it has become. ``counted`` names what ``n_usable`` counts in the message.

    Raises:
        ResourceError: over the memory limit.
    """
    rows = tracer_rows(n_usable)
    check_memory(
        2 * tracer_bytes(rows, res, subdivide),
        f"light-field tracer of {n_usable} {counted}, {rows} map rows, at geometry_res={res}, "
        f"subdivide={subdivide}",
        "lower the geometry maps' resolution (BakeConfig.geometry_res), use fewer probes, or subdivide=1",
    )


@partial(jax.jit, static_argnums=1)
def _first_rows(arrays: tuple[Array, ...], n: int) -> tuple[Array, ...]:
    """Stacks of ``n`` rows shaped like ``arrays``, row 0 set to them (one program, not one per array)."""
    return tuple(jnp.zeros((n, *a.shape), a.dtype).at[0].set(a) for a in arrays)


@partial(jax.jit, donate_argnums=0)
def _set_rows(stacks: tuple[Array, ...], arrays: tuple[Array, ...], i) -> tuple[Array, ...]:
    """``stacks[k][i] = arrays[k]`` in place (the stacks are donated): a small program per row count
    (:func:`tracer_rows`), instead of staging every probe's maps on the host and copying them back
    (2 × 3.5 MB a probe at 512²)."""
    return tuple(s.at[i].set(a) for s, a in zip(stacks, arrays, strict=True))


def _all_probe_maps(
    lf: LightFieldProbes, keep, rows: int, config: TraceConfig, table
) -> tuple[tuple[Array, ...], Array]:
    """:func:`_probe_maps` of the probes ``keep``, stacked in that order in ``rows`` rows (zeros after
    them; one probe at a time: no big program per probe count), with a progress bar when there is much to
    do; and the bordered texel directions. ``table``: the bound codes' table (:func:`bound_table`)."""
    kw = dict(sub=config.subdivide, tol=config.edge_tol, thickness=config.thickness)
    res = lf.geometry_res
    big_job = len(keep) * (res * config.subdivide) ** 2 >= 2**22  # ~ a few seconds and more
    bar = progress_bar(total=len(keep), desc=f"tracer maps {res}²", unit="probe", disable=not big_job)
    cones = cell_cones(res * config.subdivide), cell_cones(res)
    out = directions = None
    for i, p in enumerate(keep):
        # one probe's normals unpacked at a time (a 1024-probe set at 512² would be 3 GiB as float32)
        *arrays, directions = _probe_maps(lf.distance[p], lf.normal16[p], lf.far, *cones, table, **kw)
        if out is None:
            out = _first_rows(tuple(arrays), rows)
        else:
            out = _set_rows(out, tuple(arrays), np.int32(i))
        bar.update(1)
    bar.close()
    return out, directions


def _spacing(pos: np.ndarray) -> float:
    """Median distance from each probe to its nearest other probe (1 with fewer than two)."""
    if len(pos) < 2:
        return 1.0
    d, _ = cKDTree(pos).query(pos, k=2)
    return float(np.median(d[:, 1])) or 1.0


def make_tracer(
    lf: LightFieldProbes,
    bounds: Float[Array, "2 3"],
    *,
    index: GridIndex | VoxelIndex | None = None,
    config: TraceConfig = TraceConfig(),
) -> LightFieldTracer:
    """Precompute the tracer's maps and probe index from baked probes.

    Args:
        lf: baked light-field probes (the radial-distance and normal maps are used; they may have a
            resolution of their own, independent of the radiance maps').
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
    res = lf.geometry_res  # the geometry maps' resolution, whatever the radiance's
    if res < 2 or res & (res - 1):
        raise ConfigError(f"the tracer needs power-of-two distance maps, got resolution {res}")
    bn = np.asarray(bounds, np.float32)  # checked on the host: no compiled program for a check
    pos = np.asarray(lf.pos_world, np.float32)
    if not np.isfinite(pos).all():
        raise ConfigError(f"probe positions must be finite; {int((~np.isfinite(pos)).any(-1).sum())} are not")
    if bn.shape != (2, 3) or not np.isfinite(bn).all() or not (bn[1] >= bn[0]).all():
        raise ConfigError(f"bounds must be finite (min, max) corners of shape (2, 3), got {bn}")
    b = jnp.asarray(bn)
    # Inactive rows (e.g. padding to a fixed size so compiled code is reused) are not probes: skip them.
    _warn_probe_layout(pos[np.asarray(lf.active)], bn[0], bn[1], "make_tracer")
    usable = np.asarray(lf.active) & ~np.asarray(lf.inside)
    # The per-probe arrays of the usable probes only (issue 33: a grid in Sponza has 42 of 128 usable),
    # in rows padded to a bucket (tracer_rows).
    keep = np.flatnonzero(usable)
    check_tracer_memory(len(keep), res, config.subdivide)  # before the index
    if index is None:
        try:
            index = grid_index(lf)
        except ConfigError:
            index = voxel_index(lf, b)
    far = jnp.asarray(lf.far, jnp.float32)
    table = bound_table(far)  # one array: the build codes against the entries the march reads
    maps, texel_dirs = _all_probe_maps(lf, keep if len(keep) else [0], tracer_rows(len(keep)), config, table)
    rb, nb, ambiguous_bits, bound_flat, upper_flat = maps
    row = np.zeros(len(pos), np.int32)  # unusable probes: row 0, never read (the index skips them)
    row[keep] = np.arange(len(keep), dtype=np.int32)
    # scalars and masks on the host (float32 as before): each eager jnp operation is one more program
    margin = np.float32(config.bounds_margin) * np.max(bn[1] - bn[0])
    spacing = _spacing(pos[usable])
    return LightFieldTracer(
        pos_world=jnp.asarray(lf.pos_world, jnp.float32),
        usable=jnp.asarray(usable),
        row=jnp.asarray(row),
        surfel_r=rb,
        texel_dirs=texel_dirs,
        surfel_n=nb,
        ambiguous_bits=ambiguous_bits,
        bound_flat=bound_flat,
        upper_flat=upper_flat,
        bound_table=table,
        spacing=jnp.asarray(spacing, jnp.float32),
        far=far,
        t_far=jnp.asarray(np.linalg.norm(bn[1] - bn[0]) * np.float32(1.01), jnp.float32),
        bounds=jnp.asarray(np.stack([bn[0] - margin, bn[1] + margin]), jnp.float32),
        index=index,
        near=nearest_index(pos, usable, b, radius=config.fallback_radius * spacing, k=_FALLBACK_POOL),
        res=res,
        config=config,
    )


# ------------------------------------------------------------------------------------- many probes
def _sees(tr: LightFieldTracer, probes: Int[Array, " k"], x: Float[Array, "3"]) -> Bool[Array, " k"]:
    """Whether each (usable) probe sees x: x lies in front of the surfel of the march cell in x's
    direction — of every candidate surfel if the cell is ambiguous — by ``fallback_margin`` of its
    distance (the tracer's own "free" test at one point)."""
    return _sees_within(tr, probes, x, (tr.config.fallback_margin,))[0]


def _sees_within(
    tr: LightFieldTracer, probes: Int[Array, " k"], x: Float[Array, "3"], margins: tuple[float, ...]
) -> Bool[Array, "n_margins k"]:
    """:func:`_sees` at each of ``margins`` (fractions of the surfels' distance x must lie in front by; a
    negative one lets x lie behind within it: ``-thickness`` is "on the surface the probe sees",
    ``TraceConfig.surface_lookback``), reading the candidate surfels once for all of them."""
    q = jnp.maximum(probes, 0)
    rel = x[None, :] - tr.pos_world[q]
    r = jnp.linalg.norm(rel, axis=-1)
    uv = oct_encode(rel / jnp.maximum(r, 1e-12)[:, None])
    m = tr.march_res
    ij = jnp.clip(jnp.floor((uv + 1.0) * (m / 2.0)), 0, m - 1).astype(jnp.int32)[:, ::-1]

    def one(p, ij, rel):
        rows, cols = _candidates(tr, ij)
        w = tr.row[p]
        xs, n, has = tr.surfels(w, rows, cols)
        g = jnp.sum((rel[None, :] - xs) * n, axis=-1)
        r_s = jnp.linalg.norm(xs, axis=-1)
        # one surface: in front of its own plane and its concave-crease partners' (``_march._partners``)
        bounding = jnp.where(tr.is_ambiguous(w, ij[0], ij[1]), True, _partners(tr, xs, n, has))
        return jnp.stack([jnp.all(~has | (g > margin * r_s) | ~bounding) for margin in margins])

    return ((probes >= 0) & tr.usable[q])[None, :] & jax.vmap(one)(q, ij, rel).T


def _index_probe(tr, origin, direction, x, visited, prev_probe, prev_cell, prev_slot):
    """The index's next probe for a ray whose unresolved part starts at x: (probe or -1, cell id, slot).
    Candidates that see x come first."""

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
    # Rank: seeing x first, then the index's order (grid) or nearness to the ray's line (voxels).
    rank = (
        jnp.arange(cand.shape[0], dtype=jnp.float32) if isinstance(tr.index, GridIndex) else line_dist2(cand)
    )
    rank = jnp.where(_sees(tr, cand, x), 0.0, 1.0) * 1e30 + jnp.minimum(rank, 1e29)
    k = jnp.argmin(jnp.where(ok, rank, jnp.inf)).astype(jnp.int32)
    return jnp.where(ok[k], cand[k], -1), cell, slots[k]


def _lookback(tr: LightFieldTracer, origin, direction, t):
    """The point a probe must see free for the fallback to take up a ray stalled on a surface at t
    (``TraceConfig.surface_lookback``); t itself when that is off."""
    back = tr.config.surface_lookback or 0.0
    return origin + (t * (1.0 - back)) * direction


def _seeing_probe(tr: LightFieldTracer, x: Float[Array, "3"], x_back, visited) -> Int[Array, ""]:
    """The untried probe nearest x, within ``fallback_radius`` probe spacings, that sees x (:func:`_sees`),
    or -1: the fallback when the index's candidates are spent. A far probe's texels are too coarse to
    vouch for the space around x (a surface a few centimetres from x is sub-texel to it), hence the
    radius. The candidates are those :func:`nearest_index` lists for x's voxel. With
    ``surface_lookback``, a probe also qualifies when x lies on its surface and it sees ``x_back``
    (:func:`_lookback`) free."""
    pool, _ = tr.near.lookup(x)
    q = jnp.maximum(pool, 0)
    r2 = jnp.sum((tr.pos_world[q] - x[None, :]) ** 2, axis=-1)
    ok = (pool >= 0) & ~jnp.any(pool[:, None] == visited[None, :], axis=1)
    ok = ok & (r2 <= (tr.config.fallback_radius * tr.spacing) ** 2)
    if tr.config.surface_lookback is None:
        sees = _sees(tr, pool, x)
    else:
        seen, on_surface = _sees_within(tr, pool, x, (tr.config.fallback_margin, -tr.config.thickness))
        sees = seen | (on_surface & _sees(tr, pool, x_back))
    sees = ok & sees
    k = jnp.argmin(jnp.where(sees, r2, jnp.inf)).astype(jnp.int32)
    return jnp.where(sees[k], pool[k], -1).astype(jnp.int32)


def _ray_t_end(tr: LightFieldTracer, origin, direction, t_max):
    """Where the trace of a ray ends: ``t_max``, the exit from the scene's box (slab test: beyond it the
    ray is known to be free) or the scene diagonal, whichever comes first."""
    safe_d = jnp.where(jnp.abs(direction) > 1e-12, direction, 1e-12)
    t_box = jnp.min(jnp.maximum((tr.bounds[0] - origin) / safe_d, (tr.bounds[1] - origin) / safe_d))
    return jnp.clip(jnp.minimum(t_max, t_box), 0.0, tr.t_far).astype(origin.dtype)


class _RayState(NamedTuple):
    """The many-probe loop's state of ONE ray (McGuire 2017 Listing 1): the last single-probe status
    (-1: no probe left), t, probes tried (``visited``, -1 padded), their count and how many came from the
    fallback search, the cage order's previous probe / cell / slot, march steps, the last probe and its
    texel."""

    st: Array
    t: Array
    visited: Array
    n: Array
    n_fb: Array
    prev_p: Array
    prev_cell: Array
    prev_slot: Array
    steps: Array
    p: Array
    texel: Array


def _ray_state(tr: LightFieldTracer, dtype) -> _RayState:
    """A ray's state before its first probe (``st`` UNKNOWN: a probe is to be chosen)."""
    return _RayState(
        jnp.int32(TraceStatus.UNKNOWN),
        jnp.zeros((), dtype),
        -jnp.ones(tr.config.max_probes, jnp.int32),
        jnp.int32(0),
        jnp.int32(0),
        jnp.int32(-1),
        jnp.int32(-1),
        jnp.int32(0),
        jnp.int32(0),
        jnp.int32(-1),
        jnp.zeros(2, jnp.int32),
    )


def _pick_index(tr: LightFieldTracer, origin, direction, c: _RayState):
    """The index's candidate for the ray's next probe: (point x where the unresolved part starts, probe
    or -1, cell, slot, whether the index may supply it)."""
    x = origin + c.t * direction
    p_idx, cell, slot = _index_probe(tr, origin, direction, x, c.visited, c.prev_p, c.prev_cell, c.prev_slot)
    return x, p_idx, cell, slot, (p_idx >= 0) & (c.n - c.n_fb < tr.config.index_probes)


def _wants_fallback(tr: LightFieldTracer, from_index, c: _RayState):
    """Whether the fallback search's pick can be used (the index has none, the fallback share is left)."""
    return ~from_index & (c.n_fb < tr.config.fallback_probes)


def _pick(tr: LightFieldTracer, p_idx, from_index, p_fb, c: _RayState):
    """The probe to trace next: (probe or -1, found, from the fallback search)."""
    from_fb = _wants_fallback(tr, from_index, c) & (p_fb >= 0)
    p = jnp.where(from_index, p_idx, jnp.where(from_fb, p_fb, -1))
    return p, (p >= 0) & (c.n < tr.config.max_probes), from_fb


def _after_probe(
    tr: LightFieldTracer, c: _RayState, p, found, from_index, from_fb, cell, slot, probe_out, x_end
):
    """The ray's state after the single-probe trace ``probe_out`` = (status, t, steps, texel) of probe
    ``p`` (ignored unless ``found``: then the ray has no probe left, status -1). ``x_end`` is where the
    ray's trace ends (``_ray_t_end``).

    A probe's MISS is believed only if the probe sees ``x_end`` (:func:`_sees`): a march that slips past a
    texel's surfel (a corner texel, whose one surfel stands for two walls) would otherwise call a ray free
    that no ray could leave — in a closed furnace box that lost ~7 % of the glossy energy. Such a miss
    becomes UNKNOWN with no progress (t unchanged): the next probe retraces the whole unresolved part."""
    n_max = tr.config.max_probes
    st, t2, s2, texel = probe_out
    doubtful = found & (st == TraceStatus.MISS) & ~_sees(tr, jnp.maximum(p, 0)[None], x_end)[0]
    st = jnp.where(doubtful, TraceStatus.UNKNOWN, st)
    t2 = jnp.where(doubtful, c.t, t2)
    st = jnp.where(found, st, -1)  # -1: nothing left to try
    t2 = jnp.where(found & (st == TraceStatus.UNKNOWN), jnp.maximum(t2, c.t), jnp.where(found, t2, c.t))
    visited = c.visited.at[jnp.minimum(c.n, n_max - 1)].set(jnp.where(found, p, c.visited[n_max - 1]))
    return _RayState(
        st,
        t2,
        visited,
        c.n + found.astype(jnp.int32),
        c.n_fb + (found & from_fb).astype(jnp.int32),
        # The cage order continues from an index probe only; after a fallback probe it restarts.
        jnp.where(from_index, p, -1),
        cell,
        slot,
        c.steps + jnp.where(found, s2, 0),
        p,
        # With no probe left the ray keeps the texel where its last probe gave up: the trace run for a
        # missing probe (vmapped lanes all run it) is discarded whole, its texel too.
        jnp.where(found, texel, c.texel),
    )


def _ray_result(c: _RayState):
    """The fields of :class:`TraceResult` from a finished ray's state."""
    status = jnp.where(
        c.st == TraceStatus.HIT,
        jnp.int32(TraceStatus.HIT),
        jnp.where(c.st == TraceStatus.MISS, jnp.int32(TraceStatus.MISS), jnp.int32(TraceStatus.UNRESOLVED)),
    )
    t = jnp.where(status == TraceStatus.MISS, jnp.inf, c.t)
    return status, t, jnp.where(status == TraceStatus.HIT, c.p, -1), c.texel, c.steps, c.n, c.n_fb


def trace_ray(
    tr: LightFieldTracer,
    origin: Float[Array, "3"],
    direction: Float[Array, "3"],
    t_max: Float[Array, ""],
) -> tuple[
    Int[Array, ""],
    Float[Array, ""],
    Int[Array, ""],
    Int[Array, "2"],
    Int[Array, ""],
    Int[Array, ""],
    Int[Array, ""],
]:
    """Light-field trace of ONE ray through the probe set (McGuire 2017 Listing 1 ``lightFieldTrace``).

    The per-ray engine: nested loops over probes, octant pieces and march steps. The wavefront engine
    (``_wavefront``) runs the same steps as a state machine and gives the same answers.

    Returns:
        (status TraceStatus MISS / HIT / UNRESOLVED, t (inf on a miss; last free point if unresolved),
        probe, geometry texel (row, col) of the hit (of the cell where the last probe tried gave up if
        unresolved), march steps, probes tried, probes from the fallback search): int32 scalars but t
        (float) and texel (int32 (2,)), the fields of :class:`TraceResult`.
    """
    t_end = _ray_t_end(tr, origin, direction, t_max)

    def body(c: _RayState) -> _RayState:
        x, p_idx, cell, slot, from_index = _pick_index(tr, origin, direction, c)
        x_back = _lookback(tr, origin, direction, c.t)
        p_fb = _seeing_probe(tr, x, x_back, c.visited) if tr.config.fallback_probes > 0 else jnp.int32(-1)
        p, found, from_fb = _pick(tr, p_idx, from_index, p_fb, c)
        out = trace_probe(tr, jnp.maximum(p, 0), origin, direction, c.t, t_end)
        x_end = origin + t_end * direction
        return _after_probe(tr, c, p, found, from_index, from_fb, cell, slot, out, x_end)

    c = jax.lax.while_loop(lambda c: c.st == TraceStatus.UNKNOWN, body, _ray_state(tr, origin.dtype))
    return _ray_result(c)
