"""``place``: scene + method + budget (+ refiner) → :class:`PlaceResult`, and a top-view plot.

Methods come from the registry (``_registry``); this module registers the skeleton-seeded ones
(``skeleton``, ``medial``, ``skeleton+medial``: Wang 2019 seeds and the automatic budget search). Every
method ends in ``_finish`` (valid space, exact budget, coverage, refinement).
"""

from __future__ import annotations

import dataclasses
import functools
import time
from pathlib import Path
from typing import Any

import jax
import numpy as np

from .._core import ConfigError, Scene, load_pyplot, stream
from ..geometry import build_sdf
from ._finish import coverage_context, make_usable, probe_set, refine_problem, valid_settings
from ._registry import PlacementMethod, PlaceRequest, PlaceResult, get_method, register_method
from .fitness import binary_coverage, binary_visibility, probe_clearance
from .refine import get_refiner
from .skeleton import auto_budget, medial_axis_seeds, reaches_target, skeleton_seeds
from .space import grid_dims, uniform_grid


def place(
    scene: Scene,
    *,
    method: str = "skeleton+medial",
    options: dict | None = None,
    **settings: Any,
) -> PlaceResult:
    """Place probes in ``scene``.

    Args:
        scene: the scene.
        method: a registered method (:func:`method_names`): ``skeleton`` (SDF skeleton seeds), ``medial``
            (ball shrinking) or ``skeleton+medial``, searched for the fewest probes; or a baseline
            (docs/baselines.md): ``grid`` (uniform grid; a budget starts from the lattice whose usable
            count is nearest, ``"auto"`` = smallest full-coverage grid), ``lod-grid`` (Yang 2023; the
            level whose count is nearest the budget) or ``vardis`` (Vardis 2021 simplification of a dense
            grid down to the budget, ``"auto"`` = error tolerance).
        options: the method's options (its registered options dataclass, e.g. ``grid``'s ``dims``);
            must be empty for a method without options.
        **settings: the fields of :class:`PlaceRequest`, the stage's one schema (``budget``, ``refiner``,
            ``objective``, ``seed``, ``target``, ``n_opt_samples``, ``config``, ``caster``, ``clearance``,
            ``region``; its attributes say what each does); an unknown name is refused.

    Returns:
        :class:`PlaceResult`: the probes, coverage, timings, refinement status and the method's record
        (``metadata``: the JSON record for ``save_probe_set``).

    Raises:
        ConfigError: unknown method, option or setting; a setting :class:`PlaceRequest` refuses.
    """
    m = get_method(method)
    unknown = sorted(settings.keys() - {f.name for f in dataclasses.fields(PlaceRequest)})
    if unknown:
        known = [f.name for f in dataclasses.fields(PlaceRequest)]
        raise ConfigError(f"place: unknown setting {unknown[0]!r}; PlaceRequest's: {known}")
    return m.place_fn(scene, PlaceRequest(**settings), m.parse_options(options))


def _place_seeded(
    scene: Scene, request: PlaceRequest, options: None, *, method: str, seeds: tuple
) -> PlaceResult:
    """Wang 2019: candidates from the SDF skeleton and/or the medial axis (``seeds``), then the automatic
    budget search (``auto_budget``) for the fewest that reach the coverage target, optionally refined."""
    r = request
    t_all = time.perf_counter()
    timings: dict[str, float] = {}
    grid = timed(timings, "sdf_s", build_sdf, scene)
    cov = timed(timings, "problem_s", coverage_context, scene, r, grid)
    problem = cov.problem
    cand = timed(timings, "seeds_s", _seed_candidates, problem, seeds)
    reach = valid_settings(scene, r, grid)[2]
    inside_reach = None if reach is None else reach.contains(cand)
    if inside_reach is not None and inside_reach.any():  # search among probes a viewer can get to
        cand = cand[inside_reach]
    ref, opt_problem = None, None
    if r.refiner is not None:
        ref = get_refiner(r.refiner, objective=r.objective)
        opt_problem = refine_problem(scene, r, grid)
    vis_caster = cov.caster
    t0 = time.perf_counter()
    res = auto_budget(
        problem,
        key=stream(r.seed, "search"),
        target=r.target,
        refiner=ref,
        refine_problem=opt_problem,
        candidates=cand,
        max_probes=None if r.budget == "auto" else int(r.budget),
        caster=vis_caster,
    )
    timings["search_s"] = time.perf_counter() - t0
    timings.update({f"search_{k}": v for k, v in res.timings.items()})
    t0 = time.perf_counter()
    pos, record = make_usable(scene, r, res.pos, sdf=grid, cov=cov, spare=cand)
    changed = pos.shape != res.pos.shape or not np.array_equal(pos, res.pos)
    # the set auto_budget measured, or one visibility pass that also gives each probe's part
    coverage, detail = cov.measure(pos) if changed else (res.coverage, None)
    timings["usable_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_all
    clear = probe_clearance(problem, pos)
    return PlaceResult(
        probes=probe_set(pos, method),
        method=method,
        request=r,
        coverage=coverage,
        visibility=cov.visibility_name,
        timings=timings,
        refine_status=res.refine_status,
        refined=bool(res.refined) if res.refine_status is not None else False,
        # judged on the final set: relocating or refilling probes can lose a sliver of the coverage
        target_reached=reaches_target(coverage, r.target) if changed else res.reached,
        min_probe_clearance=float(clear.min()) if len(clear) else None,
        info={
            **_problem_record(problem, grid),
            "target": r.target,
            "n_candidates": res.n_candidates,
            "coverage_curve": res.curve,
            **record,
        },
        coverage_detail=detail,
        coverage_context=cov,
    )


_FITNESS_KEYS = (
    "w1",
    "w2",
    "map_res",
    "sharpness_voxels",
    "n_steps",
    "facing_softness",
    "two_sided",
    "clearance_voxels",
    "coverage",
)


def _problem_record(problem, grid) -> dict:
    """The search problem's settings and size, for the record."""
    area = np.asarray(problem.area)
    return {
        "config": {k: getattr(problem.config, k) for k in _FITNESS_KEYS},
        "voxel_size": float(grid.voxel_size),
        "n_samples": problem.n_samples,
        "coverable_area_share": float(area[np.asarray(problem.coverable)].sum() / area.sum()),
    }


def _seed_candidates(problem, seeds: tuple) -> np.ndarray:
    parts = {"skeleton": skeleton_seeds, "medial": medial_axis_seeds}
    return np.concatenate([parts[s](problem) for s in seeds])


def timed(timings: dict, name: str, fn, /, *args, **kwargs):
    """``fn(*args, **kwargs)``, its wall time in ``timings[name]``."""
    t0 = time.perf_counter()
    out = fn(*args, **kwargs)
    timings[name] = time.perf_counter() - t0
    return out


def _refining_grid_dims(lo: np.ndarray, hi: np.ndarray):
    """Grid dimensions over the box [lo, hi], coarsest first: the spacing shrinks by 10% per step and
    dimensions already produced are skipped. Endless; the caller stops."""
    spacing = float(np.max(hi - lo))
    seen: set[tuple] = set()
    while True:
        dims = grid_dims(lo, hi, spacing)
        spacing *= 0.9
        if dims not in seen:
            seen.add(dims)
            yield dims


def smallest_full_grid(problem, *, max_probes: int = 4096, target: float = 1.0) -> tuple[int, float, tuple]:
    """Smallest uniform grid (by active probe count) reaching ``target`` coverage; spacing shrinks by 10%.

    Returns (probe count, coverage, dims); count −1 if none up to ``max_probes``.
    """
    lo, hi = np.asarray(problem.lo), np.asarray(problem.hi)
    for dims in _refining_grid_dims(lo, hi):
        pos = uniform_grid(lo, hi, dims)
        pos = pos[probe_clearance(problem, pos) > 0]
        if len(pos) > max_probes:
            return -1, 0.0, dims
        cov = binary_coverage(problem, binary_visibility(problem, pos))
        if reaches_target(cov, target):
            return len(pos), cov, dims


def save_top_view(scene: Scene, pos: np.ndarray | jax.Array, path: str | Path, *, title: str = "") -> Path:
    """PNG of the probes (red) over the scene's triangles seen from above (x right, z down; +Y up)."""
    from matplotlib.collections import PolyCollection

    plt = load_pyplot()

    tri = np.asarray(scene.vertices)[np.asarray(scene.faces)]
    fig, ax = plt.subplots(figsize=(6, 6), dpi=100)
    order = np.argsort(tri[:, :, 1].mean(axis=1))  # lower triangles first
    pc = PolyCollection(
        tri[order][:, :, [0, 2]],
        facecolors=(0.6, 0.6, 0.6, 0.25),
        edgecolors=(0.3, 0.3, 0.3, 0.3),
        linewidths=0.3,
    )
    ax.add_collection(pc)
    p = np.asarray(pos).reshape(-1, 3)
    if len(p):
        sc = ax.scatter(p[:, 0], p[:, 2], c=p[:, 1], cmap="autumn", s=30, edgecolors="k", zorder=3)
        fig.colorbar(sc, ax=ax, label="height (y)", shrink=0.7)
    ax.autoscale()
    ax.set_aspect("equal")
    ax.invert_yaxis()
    ax.set_xlabel("x")
    ax.set_ylabel("z")
    ax.set_title(title or f"{scene.name}: {len(p)} probes")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


for _name, _seeds, _label in (
    ("skeleton", ("skeleton",), "SDF skeleton seeds (Wang 2019)"),
    ("medial", ("medial",), "medial-axis seeds (ball shrinking)"),
    ("skeleton+medial", ("skeleton", "medial"), "skeleton and medial-axis seeds"),
):
    register_method(
        PlacementMethod(_name, functools.partial(_place_seeded, method=_name, seeds=_seeds), label=_label)
    )
