"""The baseline placement methods (docs/baselines.md), each registered with its options: the uniform
grid, Yang 2023's mixed-resolution (LOD) grid and Vardis 2021's simplification of a dense set.

All three lay a lattice anchored to the scene's bounding box; their ``shift`` option (3-vector, scene
units) moves it (the grid, the LOD grid's box, Vardis's dense grid). The stability study moves the scene
by t and the lattice by −t, which keeps the lattice where it was in the world: a translation of the scene
*relative to the grid* (moving both together changes nothing). A ``refiner`` then moves the survivors
(:func:`finish_lattice`).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ..._core import ConfigError, Scene, host_rng, scene_box, stream
from ...geometry import build_sdf
from .._finish import finish_lattice, usable_count, valid_settings
from .._place import _refining_grid_dims, smallest_full_grid, timed
from .._registry import PlacementMethod, PlaceRequest, PlaceResult, register_method
from ..fitness import make_problem

_ZERO3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class GridOptions:
    """``grid`` options.

    Attributes:
        dims: probes per axis; ``None``: from the budget (``"auto"``: the smallest full-coverage grid).
        inside: probes inside geometry: ``keep``, ``disable`` or ``relocate``.
        jitter: random offset of each probe, as a fraction of a cell.
        offset: lattice shift in fractions of a cell per axis.
        shift: lattice shift in scene units (module docstring).
    """

    dims: Any = None
    inside: str = "disable"
    jitter: float = 0.0
    offset: Any = _ZERO3
    shift: Any = _ZERO3


@dataclass(frozen=True)
class LodGridOptions:
    """``lod-grid`` options.

    Attributes:
        base_divisions: base cells per axis; ``None``: about 4 on the longest side, cubic cells.
        levels: subdivision levels (with a budget: the finest level that fits it).
        shift: lattice shift in scene units (module docstring).
    """

    base_divisions: Any = None
    levels: int = 3
    shift: Any = _ZERO3


@dataclass(frozen=True)
class VardisOptions:
    """``vardis`` options (``vardis_simplify`` and ``dense_probe_sh``).

    Attributes:
        shift: lattice shift of the dense grid in scene units (module docstring).
        dense: the dense set: ``grid`` or ``poisson``.
        dense_probes: about this many dense probes.
        inside: dense grid probes inside geometry (as ``grid``'s).
        n_eval: evaluation points; ``eval_points``: ``surface`` or ``grid``.
        n_dirs, spp, max_depth: the dense probes' SH estimate.
        error, weights, per_iteration, lazy: ``vardis_simplify``'s.
        tolerance: error tolerance of budget ``"auto"``.
        progress: progress bar.
    """

    shift: Any = _ZERO3
    dense: str = "grid"
    dense_probes: int = 512
    inside: str = "disable"
    n_eval: int = 1024
    eval_points: str = "surface"
    n_dirs: int = 64
    spp: int = 4
    max_depth: int = 4
    error: str = "sh"
    weights: str = "chrominance"
    per_iteration: int = 1
    lazy: bool = False
    tolerance: float = 0.05
    progress: bool = False


def _shift(method: str, options) -> np.ndarray:
    shift = np.broadcast_to(np.asarray(options.shift, np.float64), (3,))
    if not np.all(np.isfinite(shift)):
        raise ConfigError(
            f"{method} option shift must be a finite 3-vector (scene units), got {options.shift}"
        )
    return shift


def _grid_dims_for_budget(scene: Scene, request: PlaceRequest, inside: str, sdf) -> tuple:
    """The uniform grid (spacing shrinking by 10%) whose usable probe count (``_finish.usable_count``:
    active, valid and reachable) is nearest the budget (the coarser on a tie); ``_finish`` then trims or
    fills it to exactly the budget. ``sdf`` (the scene's, built once by the caller) classifies the probes
    inside geometry for every candidate."""
    from ._uniform import uniform_probe_grid

    lo, hi = scene_box(scene)
    budget = int(request.budget)
    best, best_n = (1, 1, 1), None
    for dims in _refining_grid_dims(lo, hi):
        if int(np.prod(dims)) > 64 * budget + 64:
            return best
        probes = uniform_probe_grid(scene, dims=dims, inside=inside, sdf=sdf).probes
        active = np.asarray(probes.pos_world)[np.asarray(probes.active)]
        n = len(active) if inside == "keep" else usable_count(scene, request, active, sdf=sdf)
        if best_n is None or abs(n - budget) < abs(best_n - budget):
            best, best_n = dims, n
        if n >= budget:
            return best


def place_grid(scene: Scene, request: PlaceRequest, options: GridOptions) -> PlaceResult:
    """Uniform grid: ``dims`` given, or the finest within the budget, or (``"auto"``) the smallest that
    reaches full coverage; ``offset`` and ``shift`` move it against the geometry (alignment study)."""
    from ._uniform import uniform_probe_grid

    shift = _shift("grid", options)
    t_all, timings = time.perf_counter(), {}
    k_g = stream(request.seed, "grid")
    sdf = _build_sdf(scene, timings)  # PERF: once, for every candidate grid's inside test and the coverage
    lo, hi = scene_box(scene)
    t0 = time.perf_counter()
    dims = options.dims
    if dims is None and request.budget == "auto":
        n, _, dims = smallest_full_grid(make_problem(scene, key=stream(request.seed, "coverage"), grid=sdf))
        if n < 0:
            raise ConfigError("no uniform grid up to 4096 probes reaches full coverage; give a budget")
    elif dims is None:
        dims = _grid_dims_for_budget(scene, request, options.inside, sdf)
    jitter = float(options.jitter)
    cell = (hi - lo) / np.broadcast_to(np.asarray(dims, np.float64), (3,))
    offset = np.asarray(options.offset, np.float64) + shift / cell
    r = uniform_probe_grid(
        scene,
        dims=dims,
        inside=options.inside,
        jitter=jitter,
        key=k_g if jitter else None,
        offset=offset,
        sdf=sdf,
    )
    timings["build_s"] = time.perf_counter() - t0
    info = {
        "config": {**asdict(options), "dims": list(r.dims)},
        "n_inside": r.n_inside,
        "n_disabled": r.n_disabled,
        "n_relocated": r.n_relocated,
    }
    active = np.asarray(r.probes.active)
    pos = np.asarray(r.probes.pos_world)[active]
    valid = options.inside != "keep"  # "keep" shows the classic failure: no relocation either
    return finish_lattice(
        scene,
        request,
        "grid",
        pos,
        sdf=sdf,
        timings=timings,
        t_all=t_all,
        info=info,
        valid=valid,
        relocated=np.asarray(r.relocated, bool)[active],
    )


def place_lod_grid(scene: Scene, request: PlaceRequest, options: LodGridOptions) -> PlaceResult:
    """Yang 2023's mixed-resolution grid at ``levels``, or with a budget the level (≤ ``levels``) whose usable
    probe count (``_finish.usable_count``) is nearest it (the coarser on a tie), then trimmed or filled to
    it by ``_finish``."""
    from ._lod_grid import lod_probe_grid

    shift = _shift("lod-grid", options)
    t_all, timings = time.perf_counter(), {}
    sdf = _build_sdf(scene, timings)
    lo, hi = scene_box(scene)
    t0 = time.perf_counter()
    base = options.base_divisions
    if base is None:
        base = tuple(int(max(1, round(4 * e / np.max(hi - lo)))) for e in hi - lo)
    budget = request.budget
    levels = range(int(options.levels) + 1) if budget != "auto" else [int(options.levels)]
    g, g_n = None, 0
    for lvl in levels:
        level = lod_probe_grid(
            scene, base_divisions=tuple(base), sub_division_level=lvl, bounds=(lo + shift, hi + shift)
        )
        if budget == "auto":
            g = level
            break
        n = usable_count(scene, request, level.positions, sdf=sdf)  # valid and reachable, as _finish keeps
        if g is None or abs(n - int(budget)) < abs(g_n - int(budget)):
            g, g_n = level, n
        if n >= int(budget):
            break
    timings["build_s"] = time.perf_counter() - t0
    info = {
        "config": {**asdict(options), "base_divisions": list(base), "levels": int(g.sub_division_level)},
        "lod_levels": np.bincount(g.levels, minlength=g.sub_division_level + 1).tolist(),
    }
    return finish_lattice(
        scene, request, "lod-grid", g.positions, sdf=sdf, timings=timings, t_all=t_all, info=info
    )


def _dense_set(scene: Scene, options: VardisOptions, shift: np.ndarray, key) -> np.ndarray:
    """Vardis's dense probe set: a grid (moved by ``shift``) or Poisson-disk samples."""
    from ._uniform import uniform_probe_grid
    from ._vardis import poisson_disk_probes

    lo, hi = scene_box(scene)
    spacing = float(np.prod(hi - lo) / int(options.dense_probes)) ** (1 / 3)
    if options.dense == "grid":
        r = uniform_probe_grid(scene, spacing=spacing, inside=options.inside, offset=shift / spacing)
        return np.asarray(r.probes.pos_world)[np.asarray(r.probes.active)]
    if options.dense == "poisson":
        return poisson_disk_probes(scene, 0.9 * spacing, key=key)
    raise ConfigError(f"vardis dense must be 'grid' or 'poisson', got {options.dense!r}")


def place_vardis(scene: Scene, request: PlaceRequest, options: VardisOptions) -> PlaceResult:
    """Vardis 2021: greedy removal from a dense set down to the budget (``"auto"``: to ``tolerance``)."""
    from ._vardis import check_vardis_light, dense_probe_sh, evaluation_points, vardis_simplify

    check_vardis_light(scene)  # before the SDF: the probe values are path traced
    shift = _shift("vardis", options)
    t_all, timings = time.perf_counter(), {}
    k_g, k_v, k_e = (stream(request.seed, f"vardis-{n}") for n in ("dense", "values", "eval-points"))
    sdf = _build_sdf(scene, timings)
    t0 = time.perf_counter()
    dense = _dense_set(scene, options, shift, k_g)
    reach = valid_settings(scene, request, sdf)[2]
    n_unreachable = 0
    if reach is not None and reach.contains(dense).any():  # simplify what a viewer can get to (_reach)
        n_unreachable = int((~reach.contains(dense)).sum())
        dense = dense[reach.contains(dense)]
    timings["dense_s"] = time.perf_counter() - t0
    o = options
    values = timed(
        timings,
        "probe_values_s",
        dense_probe_sh,
        scene,
        dense,
        n_dirs=o.n_dirs,
        spp=o.spp,
        max_depth=o.max_depth,
        key=k_v,
    )
    pts = timed(
        timings, "eval_points_s", evaluation_points, scene, int(o.n_eval), key=k_e, kind=o.eval_points
    )
    auto = request.budget == "auto"
    res = timed(
        timings,
        "simplify_s",
        vardis_simplify,
        dense,
        values,
        pts,
        target=None if auto else min(int(request.budget), len(dense)),
        tolerance=float(o.tolerance) if auto else None,
        error=o.error,
        weights=o.weights,
        per_iteration=o.per_iteration,
        lazy=bool(o.lazy),
        progress=bool(o.progress),
        tet_seed=int(host_rng(stream(request.seed, "vardis-tet")).integers(2**31)),
    )
    timings["build_s"] = time.perf_counter() - t0
    info = {
        "config": asdict(options),
        "n_dense": len(dense),
        "n_dense_unreachable": n_unreachable,
        "vardis_error": res.error,
        "vardis_iterations": res.n_iterations,
        "vardis_history": {"count": res.history_count.tolist(), "error": res.history_error.tolist()},
    }
    spare = np.delete(dense, res.keep, axis=0)  # the removed dense probes: the first to fill with
    return finish_lattice(
        scene,
        request,
        "vardis",
        dense[res.keep],
        sdf=sdf,
        timings=timings,
        t_all=t_all,
        info=info,
        spare=spare,
    )


def _build_sdf(scene: Scene, timings: dict):
    return timed(timings, "sdf_s", build_sdf, scene)


register_method(
    PlacementMethod("grid", place_grid, GridOptions, "uniform grid", lattice=True, reference=True)
)
register_method(
    PlacementMethod(
        "lod-grid",
        place_lod_grid,
        LodGridOptions,
        "mixed-resolution grid (Yang 2023)",
        lattice=True,
        reference=True,
    )
)
register_method(
    PlacementMethod(
        "vardis", place_vardis, VardisOptions, "dense-set simplification (Vardis 2021)", lattice=True
    )
)
