"""``place``: scene + seed method + budget (+ refiner) → ProbeSet with metadata, and a top-view plot."""

from __future__ import annotations

import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from .._core import ConfigError, ProbeSet, Scene, load_pyplot, scene_box
from ..geometry import build_sdf
from ._auto import auto_budget
from ._fitness import FitnessConfig, binary_coverage, binary_visibility, make_problem, probe_clearance
from ._grid import grid_dims, uniform_grid
from ._refine import REFINERS, get_refiner
from ._seeds import medial_axis_seeds, skeleton_seeds

BASELINE_METHODS = ("grid", "lod-grid", "vardis")  # --- baselines (issue 6): _place_baseline below ---
METHODS = ("skeleton", "medial", "skeleton+medial", *BASELINE_METHODS)


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
    caster: str | None = "auto",
    options: dict | None = None,
) -> tuple[ProbeSet, dict]:
    """Place probes in ``scene``.

    Args:
        scene: the scene.
        method: candidate generator: ``skeleton`` (SDF skeleton), ``medial`` (ball shrinking) or both; or a
            baseline (docs/baselines.md): ``grid`` (uniform grid; budget = max probes, ``"auto"`` = smallest
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
            imports, else the SDF tracer), ``"embree"``, or ``None``/``"sdf"`` (SDF sphere tracer).
        options: baseline options (:func:`_place_baseline`); must be empty for the other methods.

    Returns:
        (probes, metadata) — metadata holds method, config, seed, timings, coverage, curve.

    Raises:
        ConfigError: unknown method / refiner, bad budget.
    """
    if method not in METHODS:
        raise ConfigError(f"method must be one of {METHODS}, got {method!r}")
    if refiner is not None and refiner not in REFINERS:
        raise ConfigError(f"refiner must be one of {REFINERS} or None, got {refiner!r}")
    if budget != "auto" and not (isinstance(budget, int) and budget >= 1):
        raise ConfigError(f"budget must be 'auto' or a positive integer, got {budget!r}")
    if method in BASELINE_METHODS:
        return _place_baseline(
            scene, method, budget, refiner, objective, seed, n_opt_samples, dict(options or {}), caster
        )
    if options:
        raise ConfigError(f"options apply to the methods {BASELINE_METHODS} only, got {sorted(options)}")
    t_all = time.perf_counter()
    timings: dict[str, float] = {}
    key = jax.random.key(seed)
    k_s, k_o, k_r = jax.random.split(key, 3)
    t0 = time.perf_counter()
    grid = build_sdf(scene)
    timings["sdf_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    problem = make_problem(scene, key=k_s, grid=grid, config=config)
    timings["problem_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    parts = []
    if method in ("skeleton", "skeleton+medial"):
        parts.append(skeleton_seeds(problem))
    if method in ("medial", "skeleton+medial"):
        parts.append(medial_axis_seeds(problem))
    cand = np.concatenate(parts)
    timings["seeds_s"] = time.perf_counter() - t0
    ref = None
    opt_problem = None
    if refiner is not None:
        ref = get_refiner(refiner, objective=objective)
        opt_problem = make_problem(
            scene,
            key=k_o,
            grid=grid,
            n_samples=n_opt_samples,
            config=FitnessConfig(n_steps=16) if config is None else config,
        )
    t0 = time.perf_counter()
    res = auto_budget(
        problem,
        key=k_r,
        target=target,
        refiner=ref,
        refine_problem=opt_problem,
        candidates=cand,
        max_probes=None if budget == "auto" else int(budget),
        caster=(vis_caster := _search_caster(scene, caster)),
    )
    timings["search_s"] = time.perf_counter() - t0
    timings.update({f"search_{k}": v for k, v in res.timings.items()})
    timings["total_s"] = time.perf_counter() - t_all
    pos = res.pos
    probes = ProbeSet(pos_world=jnp.asarray(pos), active=jnp.ones(len(pos), bool), method=method)
    clear = probe_clearance(problem, pos)
    meta = {
        "method": method,
        "budget": budget,
        "refiner": refiner,
        "objective": objective,
        "seed": seed,
        "target": target,
        "visibility": "sdf" if vis_caster is None else type(vis_caster).__name__,
        "config": {
            k: getattr(problem.config, k)
            for k in (
                "w1",
                "w2",
                "map_res",
                "sharpness_voxels",
                "n_steps",
                "facing_softness",
                "two_sided",
                "clearance_voxels",
            )
        },
        "voxel_size": float(grid.voxel_size),
        "n_samples": problem.n_samples,
        "coverable_area_share": float(
            np.asarray(problem.area)[np.asarray(problem.coverable)].sum() / np.asarray(problem.area).sum()
        ),
        "n_probes": len(pos),
        "n_candidates": res.n_candidates,
        "coverage": res.coverage,
        "target_reached": res.reached,
        **_refine_report(res.refine_status, res.refined),
        "coverage_curve": res.curve,
        "min_probe_clearance": float(clear.min()) if len(clear) else None,
        "timings": timings,
    }
    return probes, meta


def _refine_report(status: str | None, kept: bool) -> dict:
    """Metadata of the refinement step: its status, whether it converged (the solver stopped on its
    tolerance, not on ``max_steps`` or a non-finite objective; the fixed-sweep Gibbs and ascent refiners
    count as converged when they finish finite) and whether its positions were kept."""
    if status is None:
        return {"refined": False}
    return {"refine_status": status, "refine_converged": status == "ok", "refined": bool(kept)}


def _search_caster(scene: Scene, caster: str | None):
    """The exact caster of the binary visibility (PERF: Embree occlusion rays), or None (SDF tracer)."""
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


# --- baselines (issue 6): uniform grid, Yang 2023 LOD grid and Vardis 2021 as ``place`` methods ---
BASELINE_OPTIONS = {
    "grid": {
        "dims": None,
        "inside": "disable",
        "jitter": 0.0,
        "offset": [0.0, 0.0, 0.0],
        "shift": [0.0, 0.0, 0.0],
    },
    "lod-grid": {"base_divisions": None, "levels": 3, "shift": [0.0, 0.0, 0.0]},
    "vardis": {
        "shift": [0.0, 0.0, 0.0],
        "dense": "grid",
        "dense_probes": 512,
        "inside": "disable",
        "n_eval": 1024,
        "eval_points": "surface",
        "n_dirs": 64,
        "spp": 4,
        "max_depth": 4,
        "error": "sh",
        "weights": "chrominance",
        "per_iteration": 1,
        "lazy": False,
        "tolerance": 0.05,
        "progress": False,
    },
}


def _grid_dims_for_budget(scene: Scene, budget: int, inside: str, sdf) -> tuple:
    """Finest uniform grid (spacing shrinking by 10%) with at most ``budget`` active probes; ``sdf`` (the
    scene's, built once by the caller) classifies the probes inside geometry for every candidate."""
    from ._uniform import uniform_probe_grid

    lo, hi = scene_box(scene)
    best = (1, 1, 1)
    for dims in _refining_grid_dims(lo, hi):
        if int(np.prod(dims)) > 64 * budget + 64:
            return best
        n = uniform_probe_grid(scene, dims=dims, inside=inside, sdf=sdf).probes.n_active
        if n > budget:
            return best
        best = dims


def _place_baseline(
    scene, method, budget, refiner, objective, seed, n_opt_samples, options, caster="auto"
) -> tuple:
    """The baseline methods of :func:`place`; ``options`` (defaults :data:`BASELINE_OPTIONS`):

    * ``grid``: ``dims`` (else from the budget), ``inside`` (keep / disable / relocate), ``jitter``,
      ``offset`` (lattice shift in fractions of a cell per axis);
    * ``lod-grid``: ``base_divisions`` (default: about 4 cells on the longest side, cubic cells), ``levels``;
    * ``vardis``: ``dense`` (``grid`` / ``poisson``), ``dense_probes`` (about this many), ``inside``,
      ``n_eval`` and ``eval_points`` (``surface`` / ``grid``), ``n_dirs`` / ``spp`` / ``max_depth`` of the
      probe SH, ``error``, ``weights``, ``per_iteration``, ``lazy``, ``tolerance`` (budget ``"auto"``);
    * all three: ``shift`` (3-vector, scene units) moves the lattice (the grid, the LOD grid's coverage box,
      Vardis's dense grid) away from the scene's bounding box, where it is otherwise anchored. The stability
      study moves the scene by t and the lattice by −t, which keeps the lattice where it was in the world:
      a translation of the scene *relative to the grid* (moving both together changes nothing).

    A ``refiner`` then moves the survivors on the coverage ``objective`` (Vardis 2021 §4's "global
    optimiser as a last step"), kept only if binary coverage does not drop (``metadata["refined"]``).
    Coverage is measured with the same binary visibility as the skeleton search (``caster``: Embree
    occlusion rays when available), so the methods' coverages compare like for like.
    """
    from ._lod_grid import lod_probe_grid
    from ._uniform import uniform_probe_grid
    from ._vardis import dense_probe_sh, evaluation_points, poisson_disk_probes, vardis_simplify

    unknown = set(options) - set(BASELINE_OPTIONS[method])
    if unknown:
        known = sorted(BASELINE_OPTIONS[method])
        raise ConfigError(f"unknown {method} options {sorted(unknown)}; known: {known}")
    opts = {**BASELINE_OPTIONS[method], **options}
    shift = np.broadcast_to(np.asarray(opts["shift"], np.float64), (3,))
    if not np.all(np.isfinite(shift)):
        raise ConfigError(
            f"{method} option shift must be a finite 3-vector (scene units), got {opts['shift']}"
        )
    t_all = time.perf_counter()
    timings: dict[str, float] = {}
    k_g, k_v, k_e, k_r = jax.random.split(jax.random.key(seed), 4)
    extra: dict = {}
    t0 = time.perf_counter()
    sdf = build_sdf(scene)  # PERF: once, for every candidate grid's inside test and for the coverage problem
    timings["sdf_s"] = time.perf_counter() - t0
    lo, hi = scene_box(scene)  # every lattice below is anchored to it (then moved by ``shift``)
    t0 = time.perf_counter()
    if method == "grid":
        dims = opts["dims"]
        if dims is None and budget == "auto":
            n, _, dims = smallest_full_grid(make_problem(scene, key=k_g, grid=sdf))
            if n < 0:
                raise ConfigError("no uniform grid up to 4096 probes reaches full coverage; give a budget")
        elif dims is None:
            dims = _grid_dims_for_budget(scene, int(budget), opts["inside"], sdf)
        jitter = float(opts["jitter"])
        key = k_g if jitter else None
        # ``offset`` (fraction of a cell) and ``shift`` (scene units) move the lattice against the geometry:
        # the alignment study of the stability preset.
        cell = (hi - lo) / np.broadcast_to(np.asarray(dims, np.float64), (3,))
        offset = np.asarray(opts["offset"], np.float64) + shift / cell
        r = uniform_probe_grid(
            scene, dims=dims, inside=opts["inside"], jitter=jitter, key=key, offset=offset, sdf=sdf
        )
        pos = np.asarray(r.probes.pos_world)[np.asarray(r.probes.active)]
        opts["dims"] = list(r.dims)
        extra = {"n_inside": r.n_inside, "n_disabled": r.n_disabled, "n_relocated": r.n_relocated}
    elif method == "lod-grid":
        base = opts["base_divisions"]
        if base is None:
            base = tuple(int(max(1, round(4 * e / np.max(hi - lo)))) for e in hi - lo)
        opts["base_divisions"] = list(base)
        levels = list(range(int(opts["levels"]) + 1)) if budget != "auto" else [int(opts["levels"])]
        g = None
        for lvl in levels[::-1]:
            g = lod_probe_grid(
                scene, base_divisions=tuple(base), sub_division_level=lvl, bounds=(lo + shift, hi + shift)
            )
            if budget == "auto" or g.probe_count <= int(budget):
                break
        if budget != "auto" and g.probe_count > int(budget):
            raise ConfigError(f"even the base grid {tuple(base)} has {g.probe_count} > {budget} probes")
        pos = g.positions
        opts["levels"] = int(g.sub_division_level)
        extra = {"lod_levels": np.bincount(g.levels, minlength=g.sub_division_level + 1).tolist()}
    else:
        spacing = float(np.prod(hi - lo) / int(opts["dense_probes"])) ** (1 / 3)
        if opts["dense"] == "grid":
            r = uniform_probe_grid(scene, spacing=spacing, inside=opts["inside"], offset=shift / spacing)
            dense = np.asarray(r.probes.pos_world)[np.asarray(r.probes.active)]
        elif opts["dense"] == "poisson":
            dense = poisson_disk_probes(scene, 0.9 * spacing, key=k_g)
        else:
            raise ConfigError(f"vardis dense must be 'grid' or 'poisson', got {opts['dense']!r}")
        timings["dense_s"] = time.perf_counter() - t0
        t1 = time.perf_counter()
        values = dense_probe_sh(
            scene, dense, n_dirs=opts["n_dirs"], spp=opts["spp"], max_depth=opts["max_depth"], key=k_v
        )
        timings["probe_values_s"] = time.perf_counter() - t1
        t1 = time.perf_counter()
        pts = evaluation_points(scene, int(opts["n_eval"]), key=k_e, kind=opts["eval_points"])
        timings["eval_points_s"] = time.perf_counter() - t1
        t1 = time.perf_counter()
        res = vardis_simplify(
            dense,
            values,
            pts,
            target=None if budget == "auto" else max(4, min(int(budget), len(dense))),
            tolerance=float(opts["tolerance"]) if budget == "auto" else None,
            error=opts["error"],
            weights=opts["weights"],
            per_iteration=opts["per_iteration"],
            lazy=bool(opts["lazy"]),
            progress=bool(opts["progress"]),
        )
        timings["simplify_s"] = time.perf_counter() - t1
        pos = dense[res.keep]
        extra = {
            "n_dense": len(dense),
            "vardis_error": res.error,
            "vardis_iterations": res.n_iterations,
            "vardis_history": {"count": res.history_count.tolist(), "error": res.history_error.tolist()},
        }
    timings["build_s"] = time.perf_counter() - t0
    pos = np.asarray(pos, np.float32)
    t0 = time.perf_counter()
    cov_problem = make_problem(scene, key=jax.random.key(seed), grid=sdf)
    vis_caster = _search_caster(scene, caster)

    def coverage_of_pos(p: np.ndarray) -> float:
        return binary_coverage(cov_problem, binary_visibility(cov_problem, p, caster=vis_caster))

    coverage = coverage_of_pos(pos)
    timings["coverage_s"] = time.perf_counter() - t0
    refined, refine_status = False, None
    if refiner is not None:
        t0 = time.perf_counter()
        opt_problem = make_problem(
            scene, key=k_r, grid=sdf, n_samples=n_opt_samples, config=FitnessConfig(n_steps=16)
        )
        out = get_refiner(refiner, objective=objective).refine(opt_problem, jnp.asarray(pos), key=k_r)
        refine_status = out.status_message()
        new = np.asarray(out.pos, np.float32)
        new_cov = coverage_of_pos(new)
        if np.all(np.isfinite(new)) and new_cov >= coverage:
            pos, coverage, refined = new, new_cov, True
        timings["refine_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_all
    probes = ProbeSet(pos_world=jnp.asarray(pos), active=jnp.ones(len(pos), bool), method=method)
    meta = {
        "method": method,
        "budget": budget,
        "refiner": refiner,
        **_refine_report(refine_status, refined),
        "objective": objective,
        "seed": seed,
        "config": opts,
        "n_probes": len(pos),
        "coverage": coverage,
        "visibility": "sdf" if vis_caster is None else type(vis_caster).__name__,
        "timings": timings,
        **extra,
    }
    return probes, meta
