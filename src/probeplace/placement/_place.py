"""``place``: scene + method + budget (+ refiner) → :class:`PlaceResult`, and a top-view plot.

Methods come from the registry (``_registry``); this module registers the skeleton-seeded ones
(``skeleton``, ``medial``, ``skeleton+medial``: Wang 2019 seeds and the automatic budget search) and holds
the steps the lattice methods (``_baselines``) share: binary coverage and the optional refinement.
"""

from __future__ import annotations

import functools
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from .._core import ConfigError, ProbeSet, Scene, load_pyplot
from ..geometry import AbstractRayCaster, build_sdf
from ._auto import auto_budget
from ._fitness import FitnessConfig, binary_coverage, binary_visibility, make_problem, probe_clearance
from ._grid import grid_dims, uniform_grid
from ._refine import get_refiner
from ._registry import PlacementMethod, PlaceRequest, PlaceResult, get_method, register_method
from ._seeds import medial_axis_seeds, skeleton_seeds


def place(
    scene: Scene,
    *,
    method: str = "skeleton+medial",
    budget: int | str = "auto",
    refiner: str | None = None,
    objective: str = "coverage",
    seed: int = 0,
    target: float = 1.0,
    n_opt_samples: int = 1500,
    config: FitnessConfig | None = None,
    caster: str | AbstractRayCaster | None = "auto",
    options: dict | None = None,
) -> PlaceResult:
    """Place probes in ``scene``.

    Args:
        scene: the scene.
        method: a registered method (:func:`method_names`): ``skeleton`` (SDF skeleton seeds), ``medial``
            (ball shrinking) or ``skeleton+medial``, searched for the fewest probes; or a baseline
            (docs/baselines.md): ``grid`` (uniform grid; budget = max probes, ``"auto"`` = smallest
            full-coverage grid), ``lod-grid`` (Yang 2023; budget = max probes over levels) or ``vardis``
            (Vardis 2021 simplification of a dense grid; budget = target count, ``"auto"`` = error tolerance).
        budget: ``"auto"`` (fewest probes reaching ``target`` coverage) or a maximum probe count.
        refiner: registry name (:data:`REFINERS`) or ``None``; refines on the soft ``objective`` with
            ``n_opt_samples`` surface samples and is kept only if binary coverage does not drop.
        objective: ``coverage`` or ``wang``.
        seed: PRNG seed (samples, refinement).
        target: coverage target of the search.
        n_opt_samples: samples of the refiner's problem.
        config: fitness parameters.
        caster: binary visibility of the search: ``"auto"`` (exact Embree occlusion rays when embreex
            imports, else the SDF tracer), ``"embree"``, ``None``/``"sdf"`` (SDF sphere tracer), or a caster
            object (any ``geometry.AbstractRayCaster``: its ``occluded_host`` decides).
        options: the method's options (its registered options dataclass, e.g. ``grid``'s ``dims``);
            must be empty for a method without options.

    Returns:
        :class:`PlaceResult`: the probes, coverage, timings, refinement status and the method's record
        (``metadata``: the JSON record for ``save_probe_set``).

    Raises:
        ConfigError: unknown method / refiner / option / objective, bad budget, target or
            n_opt_samples (:class:`PlaceRequest`).
    """
    m = get_method(method)
    request = PlaceRequest(budget, refiner, objective, seed, target, n_opt_samples, config, caster)
    return m.place_fn(scene, request, m.parse_options(options))


def _place_seeded(
    scene: Scene, request: PlaceRequest, options: None, *, method: str, seeds: tuple
) -> PlaceResult:
    """Wang 2019: candidates from the SDF skeleton and/or the medial axis (``seeds``), then the automatic
    budget search (``auto_budget``) for the fewest that reach the coverage target, optionally refined."""
    r = request
    t_all = time.perf_counter()
    timings: dict[str, float] = {}
    k_s, k_o, k_r = jax.random.split(jax.random.key(r.seed), 3)
    grid = timed(timings, "sdf_s", build_sdf, scene)
    problem = timed(timings, "problem_s", make_problem, scene, key=k_s, grid=grid, config=r.config)
    cand = timed(timings, "seeds_s", _seed_candidates, problem, seeds)
    ref, opt_problem = None, None
    if r.refiner is not None:
        ref = get_refiner(r.refiner, objective=r.objective)
        opt_problem = _refine_problem(scene, k_o, grid, r)
    vis_caster = _search_caster(scene, r.caster)
    t0 = time.perf_counter()
    res = auto_budget(
        problem,
        key=k_r,
        target=r.target,
        refiner=ref,
        refine_problem=opt_problem,
        candidates=cand,
        max_probes=None if r.budget == "auto" else int(r.budget),
        caster=vis_caster,
    )
    timings["search_s"] = time.perf_counter() - t0
    timings.update({f"search_{k}": v for k, v in res.timings.items()})
    timings["total_s"] = time.perf_counter() - t_all
    clear = probe_clearance(problem, res.pos)
    return PlaceResult(
        probes=_probe_set(res.pos, method),
        method=method,
        request=r,
        coverage=res.coverage,
        visibility=_visibility_name(vis_caster),
        timings=timings,
        refine_status=res.refine_status,
        refined=bool(res.refined) if res.refine_status is not None else False,
        target_reached=res.reached,
        min_probe_clearance=float(clear.min()) if len(clear) else None,
        info={
            **_problem_record(problem, grid),
            "target": r.target,
            "n_candidates": res.n_candidates,
            "coverage_curve": res.curve,
        },
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


def _refine_problem(scene: Scene, key, grid, request: PlaceRequest):
    """The refiner's (smaller) problem: ``n_opt_samples`` samples, 16 march steps unless a config is given."""
    config = FitnessConfig(n_steps=16) if request.config is None else request.config
    return make_problem(scene, key=key, grid=grid, n_samples=request.n_opt_samples, config=config)


def _probe_set(pos, method: str) -> ProbeSet:
    return ProbeSet(pos_world=jnp.asarray(pos), active=jnp.ones(len(pos), bool), method=method)


def _visibility_name(caster) -> str:
    return "sdf" if caster is None else type(caster).__name__


def _search_caster(scene: Scene, caster: str | AbstractRayCaster | None):
    """The exact caster of the binary visibility (PERF: Embree occlusion rays), or None (SDF tracer). A
    caster object is used as given; the strings pick one ("auto": Embree, else the SDF tracer — a rule of
    its own: the SDF tracer, not ``make_caster``'s BVH, is the fallback here)."""
    if isinstance(caster, AbstractRayCaster):
        return caster
    if caster in (None, "sdf"):
        return None
    if caster not in ("auto", "embree"):
        raise ConfigError(f"caster must be 'auto', 'embree', 'sdf' or None, got {caster!r}")
    from ..geometry import EmbreeUnavailableError, make_caster

    try:
        return make_caster(scene, "embree")
    except EmbreeUnavailableError:
        if caster == "embree":
            raise
        return None


def finish_lattice(
    scene: Scene,
    request: PlaceRequest,
    method: str,
    pos,
    *,
    sdf,
    key,
    timings: dict,
    t_all: float,
    info: dict,
) -> PlaceResult:
    """The common end of the lattice methods: binary coverage of ``pos`` (the same visibility as the
    skeleton search, so coverages compare like for like), then the optional refiner on the coverage
    objective (Vardis 2021 §4's "global optimiser as a last step", with ``key``), kept only if coverage
    does not drop."""
    pos = np.asarray(pos, np.float32)
    t0 = time.perf_counter()
    cov_problem = make_problem(scene, key=jax.random.key(request.seed), grid=sdf)
    vis_caster = _search_caster(scene, request.caster)

    def coverage_of_pos(p: np.ndarray) -> float:
        return binary_coverage(cov_problem, binary_visibility(cov_problem, p, caster=vis_caster))

    coverage = coverage_of_pos(pos)
    timings["coverage_s"] = time.perf_counter() - t0
    refined, status = False, None
    if request.refiner is not None:
        t0 = time.perf_counter()
        problem = make_problem(
            scene, key=key, grid=sdf, n_samples=request.n_opt_samples, config=FitnessConfig(n_steps=16)
        )
        refiner = get_refiner(request.refiner, objective=request.objective)
        out = refiner.refine(problem, jnp.asarray(pos), key=key)
        status, new = out.status_message(), np.asarray(out.pos, np.float32)
        new_cov = coverage_of_pos(new)
        if np.all(np.isfinite(new)) and new_cov >= coverage:
            pos, coverage, refined = new, new_cov, True
        timings["refine_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_all
    return PlaceResult(
        probes=_probe_set(pos, method),
        method=method,
        request=request,
        coverage=coverage,
        visibility=_visibility_name(vis_caster),
        timings=timings,
        refine_status=status,
        refined=refined,
        info=info,
    )


def coverage_of(scene: Scene, pos: np.ndarray, *, seed: int = 0) -> float:
    """Binary coverage of given positions at the default sample density (helper for comparisons)."""
    problem = make_problem(scene, key=jax.random.key(seed))
    return binary_coverage(problem, binary_visibility(problem, pos))


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
        if cov >= target * (1 - 1e-9):
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
