"""``place``: scene + seed method + budget (+ refiner) → ProbeSet with metadata, and a top-view plot."""

from __future__ import annotations

import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from .._core import ConfigError, ProbeSet, Scene
from ..geometry import build_sdf
from ._auto import auto_budget
from ._fitness import FitnessConfig, binary_coverage, binary_visibility, make_problem, probe_clearance
from ._grid import grid_dims, uniform_grid
from ._refine import REFINERS, get_refiner
from ._seeds import medial_axis_seeds, skeleton_seeds

METHODS = ("skeleton", "medial", "skeleton+medial")


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
) -> tuple[ProbeSet, dict]:
    """Place probes in ``scene``.

    Args:
        scene: the scene.
        method: candidate generator: ``skeleton`` (SDF skeleton), ``medial`` (ball shrinking) or both.
        budget: ``"auto"`` (fewest probes reaching ``target`` coverage) or a maximum probe count.
        refiner: registry name (:data:`REFINERS`) or ``None``; refines on the soft ``objective`` with
            ``n_opt_samples`` surface samples and is kept only if binary coverage does not drop.
        objective: ``coverage`` or ``wang``.
        seed: PRNG seed (samples, refinement).
        target: coverage target of the search.
        n_opt_samples: samples of the refiner's problem.
        config: fitness parameters.

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
        "coverage_curve": res.curve,
        "min_probe_clearance": float(clear.min()) if len(clear) else None,
        "timings": timings,
    }
    return probes, meta


def coverage_of(scene: Scene, pos: np.ndarray, *, seed: int = 0) -> float:
    """Binary coverage of given positions at the default sample density (helper for comparisons)."""
    problem = make_problem(scene, key=jax.random.key(seed))
    return binary_coverage(problem, binary_visibility(problem, pos))


def smallest_full_grid(problem, *, max_probes: int = 4096, target: float = 1.0) -> tuple[int, float, tuple]:
    """Smallest uniform grid (by active probe count) reaching ``target`` coverage; spacing shrinks by 10%.

    Returns (probe count, coverage, dims); count −1 if none up to ``max_probes``.
    """
    lo, hi = np.asarray(problem.lo), np.asarray(problem.hi)
    spacing = float(np.max(hi - lo))
    seen = set()
    while True:
        dims = grid_dims(lo, hi, spacing)
        spacing *= 0.9
        if dims in seen:
            continue
        seen.add(dims)
        pos = uniform_grid(lo, hi, dims)
        pos = pos[probe_clearance(problem, pos) > 0]
        if len(pos) > max_probes:
            return -1, 0.0, dims
        cov = binary_coverage(problem, binary_visibility(problem, pos))
        if cov >= target * (1 - 1e-9):
            return len(pos), cov, dims


def save_top_view(scene: Scene, pos: np.ndarray | jax.Array, path: str | Path, *, title: str = "") -> Path:
    """PNG of the probes (red) over the scene's triangles seen from above (x right, z down; +Y up)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

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
