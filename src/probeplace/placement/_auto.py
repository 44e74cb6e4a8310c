"""Automatic probe budget: the fewest probes that reach a coverage target (DESIGN.md "auto" budget).

Coverage here is binary and at the evaluation density: the share of coverable surface area seen by at
least one probe as its octahedral map decides it (:func:`binary_visibility`). The search:

1. candidates = skeleton seeds ∪ medial-axis seeds (Wang §3.1), their visibility rows computed once;
2. greedy weighted set cover: add the candidate that sees the most still-unseen area, until the target
   is met or nothing adds area (the classic ln(n)-approximation, Chvátal 1979);
3. *adding where coverage is missing*: if the target is not met, new candidates are put in front of
   unseen samples — the deepest feasible point on the sample's normal from which it is seen head-on
   (:func:`witness_positions`) —, spread over the unseen area by farthest-point sampling, and step 2
   continues;
4. refinement in between: the chosen probes are refined on the soft union coverage (a
   :class:`AbstractRefiner`); the refined set is kept only if its binary coverage does not drop;
5. *removing*: a probe whose removal keeps the coverage at the target is dropped (least unique area
   first), until none can go.

The result records the coverage-vs-count curve (coverage after each greedy addition, then after each
removal) next to the final set.
"""

from __future__ import annotations

import logging
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from scipy import spatial

from .._core import ConfigError
from ._fitness import PlacementProblem, binary_visibility, probe_clearance, witness_positions
from ._refine import AbstractRefiner
from ._seeds import medial_axis_seeds, skeleton_seeds

log = logging.getLogger(__name__)


class AutoResult(eqx.Module):
    """The outcome of :func:`auto_budget`.

    Attributes:
        pos: chosen probe positions (n, 3).
        coverage: binary coverage of ``pos`` at the evaluation density.
        curve: (count, coverage) pairs in the order the search visited them.
        n_candidates: candidates considered (seeds + gap candidates).
        reached: whether the target was met.
        timings: seconds per phase.
    """

    pos: np.ndarray
    coverage: float
    curve: list
    n_candidates: int
    reached: bool
    timings: dict


def _covered_area(vis_rows: np.ndarray, a: np.ndarray) -> float:
    return float((a * vis_rows.any(axis=0)).sum()) if len(vis_rows) else 0.0


def _greedy(vis: np.ndarray, a: np.ndarray, chosen: list[int], target_area: float, curve: list) -> list[int]:
    seen = vis[chosen].any(axis=0) if chosen else np.zeros(vis.shape[1], bool)
    while (a * seen).sum() < target_area:
        gain = (vis & ~seen[None]) @ a
        gain[chosen] = -1.0
        best = int(np.argmax(gain))
        if gain[best] <= 0:
            break
        chosen.append(best)
        seen |= vis[best]
        curve.append((len(chosen), float((a * seen).sum())))
    return chosen


def _gap_candidates(
    problem: PlacementProblem, unseen: np.ndarray, n_new: int, rng: np.random.Generator
) -> np.ndarray:
    """Positions in front of unseen samples (farthest-point spread), feasible and in the box."""
    x = np.asarray(problem.position, np.float64)[unseen]
    np.asarray(problem.normal, np.float64)[unseen]
    if len(x) == 0:
        return np.zeros((0, 3), np.float32)
    # farthest-point sampling over the unseen samples
    pick = [int(rng.integers(len(x)))]
    dist = np.linalg.norm(x - x[pick[0]], axis=1)
    for _ in range(min(n_new, len(x)) - 1):
        i = int(np.argmax(dist))
        if dist[i] <= 0:
            break
        pick.append(i)
        dist = np.minimum(dist, np.linalg.norm(x - x[i], axis=1))
    ok, q = witness_positions(problem, np.flatnonzero(unseen)[pick])
    return q[ok]


def _coverage_of(vis: np.ndarray, a: np.ndarray) -> float:
    return _covered_area(vis, a) / max(a.sum(), 1e-300)


def auto_budget(
    problem: PlacementProblem,
    *,
    key: jax.Array,
    target: float = 1.0,
    refiner: AbstractRefiner | None = None,
    refine_problem: PlacementProblem | None = None,
    candidates: np.ndarray | None = None,
    max_rounds: int = 12,
    gap_candidates: int = 32,
    max_probes: int | None = None,
    caster=None,
) -> AutoResult:
    """Fewest probes reaching ``target`` coverage (module docstring).

    Args:
        problem: the fitness model at the evaluation density (binary coverage is measured on it).
        key: PRNG key (gap-candidate spread and refinement).
        target: coverage share to reach, in (0, 1].
        refiner: refines the chosen set on ``refine_problem`` (soft objective); ``None``: no refinement.
        refine_problem: a (smaller) problem for the refiner; default ``problem``.
        candidates: start candidates; default skeleton ∪ medial-axis seeds.
        max_rounds: rounds of gap candidates before giving up.
        gap_candidates: unseen samples used per round.
        max_probes: stop adding beyond this count.
        caster: optional exact ray caster for the binary visibility.

    Raises:
        ConfigError: target outside (0, 1].
    """
    if not (0.0 < target <= 1.0):
        raise ConfigError(f"target coverage must be in (0, 1], got {target}")
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    if candidates is None:
        candidates = np.concatenate([skeleton_seeds(problem), medial_axis_seeds(problem)])
    timings["seeds_s"] = time.perf_counter() - t0
    cand = np.asarray(candidates, np.float32).reshape(-1, 3)
    cand = cand[probe_clearance(problem, cand) >= float(problem.clearance)]
    a = np.asarray(problem.area, np.float64) * np.asarray(problem.coverable)
    total = a.sum()
    # Numerically "all": a target of 1 means every coverable sample.
    target_area = target * total * (1.0 - 1e-9)
    t0 = time.perf_counter()
    vis = binary_visibility(problem, cand, caster=caster)
    timings["visibility_s"] = time.perf_counter() - t0
    rng = np.random.default_rng(np.asarray(jax.random.key_data(key)).ravel()[-1:].astype(np.uint32))
    curve: list = []
    chosen: list[int] = []
    t_greedy = time.perf_counter()
    for _ in range(max_rounds + 1):
        chosen = _greedy(vis, a, chosen, target_area, curve)
        if max_probes is not None and len(chosen) > max_probes:
            chosen = chosen[:max_probes]
        seen = vis[chosen].any(axis=0) if chosen else np.zeros(len(a), bool)
        if (a * seen).sum() >= target_area:
            break
        new = _gap_candidates(problem, (a > 0) & ~seen, gap_candidates, rng)
        if len(new) == 0:
            break
        t1 = time.perf_counter()
        vis = np.concatenate([vis, binary_visibility(problem, new, caster=caster)])
        timings["visibility_s"] += time.perf_counter() - t1
        cand = np.concatenate([cand, new])
    timings["greedy_s"] = time.perf_counter() - t_greedy - 0.0
    pos = cand[chosen]
    rows = vis[chosen]
    cov = _coverage_of(rows, a)
    # Refinement between adding and removing: keep it only if the binary coverage does not drop.
    if refiner is not None and len(pos):
        t1 = time.perf_counter()
        res = refiner.refine(refine_problem or problem, jnp.asarray(pos), key=key)
        new_pos = np.asarray(res.pos, np.float32)
        new_rows = binary_visibility(problem, new_pos, caster=caster)
        new_cov = _coverage_of(new_rows, a)
        if new_cov >= cov and np.all(probe_clearance(problem, new_pos) >= float(problem.clearance)):
            pos, rows, cov = new_pos, new_rows, new_cov
        timings["refine_s"] = time.perf_counter() - t1
    # Removal: drop probes (least unique area first) while the coverage stays at the target.
    t1 = time.perf_counter()
    goal = min(cov * total, target_area)
    keep = list(range(len(pos)))
    changed = True
    while changed and len(keep) > 1:
        changed = False
        r = rows[keep]
        count = r.sum(axis=0)
        unique = (r & (count == 1)[None]) @ a
        for j in np.argsort(unique):
            trial = [k for i, k in enumerate(keep) if i != j]
            if _covered_area(rows[trial], a) >= goal:
                keep = trial
                curve.append((len(keep), _covered_area(rows[keep], a)))
                changed = True
                break
    pos, rows = pos[keep], rows[keep]
    timings["remove_s"] = time.perf_counter() - t1
    cov = _coverage_of(rows, a)
    curve = [(int(k), float(c / max(total, 1e-300))) for k, c in curve]
    return AutoResult(
        pos=pos.astype(np.float32),
        coverage=cov,
        curve=curve,
        n_candidates=len(cand),
        reached=bool((a * rows.any(axis=0)).sum() >= target_area) if len(rows) else False,
        timings=timings,
    )


def farthest_point_subset(points: np.ndarray, k: int) -> np.ndarray:
    """Indices of k points spread by farthest-point sampling (deterministic: starts at the first)."""
    tree = spatial.cKDTree(points)
    del tree
    pick = [0]
    dist = np.linalg.norm(points - points[0], axis=1)
    for _ in range(min(k, len(points)) - 1):
        i = int(np.argmax(dist))
        pick.append(i)
        dist = np.minimum(dist, np.linalg.norm(points - points[i], axis=1))
    return np.asarray(pick)
