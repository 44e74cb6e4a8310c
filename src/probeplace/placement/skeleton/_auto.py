"""Automatic probe budget: the fewest probes that reach a coverage target (DESIGN.md "auto" budget).

Coverage here is binary and at the evaluation density: the share of coverable surface area seen by at
least one probe as its octahedral map decides it (:func:`binary_visibility`). The search:

1. candidates = skeleton seeds ∪ medial-axis seeds (Wang §3.1);
2. greedy weighted set cover: add the candidate that sees the most still-unseen area, until the target
   is met or nothing adds area (the classic ln(n)-approximation, Chvátal 1979), evaluated lazily
   (Minoux 1978: stale gains in a max-heap are upper bounds, coverage being submodular);
3. *adding where coverage is missing*: if the target is not met, new candidates are put in front of
   unseen samples — the deepest feasible point on the sample's normal from which it is seen head-on
   (:func:`witness_positions`) —, spread over the unseen area by farthest-point sampling, and step 2
   continues;
4. refinement in between: the chosen probes are refined on the request's soft objective (a
   :class:`AbstractRefiner`); the refined set is kept only if that objective improved;
5. *removing*: a probe whose removal keeps the coverage at the target is dropped (least unique area
   first), until none can go. Removing probe j loses exactly its unique area, so this needs no trial
   coverages: per-sample counts and unique owners are updated incrementally.

**Coarse-to-fine** (large atlases, e.g. Sponza's 495 k samples): step 2 first scores every candidate on
``search_samples`` coverable samples spread in space; the probes it picks are then cast at full density,
the other candidates are scored on the still-unseen samples only (one that adds nothing there never will:
the unseen set only shrinks), and so are the gap candidates of step 3. Each chosen probe's full row is
cast once (the removal needs it). Rows only cover coverable samples. Below ``search_samples`` coverable
samples (the Cornell box) the first pass is the exact greedy. docs/placement.md "Performance" has the
measurements.

The result records the coverage-vs-count curve (coverage after each greedy addition, then after each
removal) next to the final set.
"""

from __future__ import annotations

import dataclasses
import heapq
import logging
import time

import jax
import jax.numpy as jnp
import numpy as np

from ..._core import ConfigError, host_rng
from ..fitness import PlacementProblem, binary_visibility, probe_clearance, witness_positions
from ..refine import AbstractRefiner
from ._seeds import medial_axis_seeds, skeleton_seeds

log = logging.getLogger(__name__)

#: Relative tolerance of "the target is reached": a coverage share within this of the target counts
#: (numerically "all" for a target of 1). The one tolerance for ``target_reached`` and the runner's
#: ``coverage<100%`` failure (:func:`reaches_target`).
COVERAGE_RTOL = 1e-9


def reaches_target(coverage: float, target: float = 1.0) -> bool:
    """Whether a coverage share reaches ``target`` up to :data:`COVERAGE_RTOL` (``target_reached``)."""
    return float(coverage) >= float(target) * (1.0 - COVERAGE_RTOL)


@dataclasses.dataclass(frozen=True)
class AutoResult:
    """The outcome of :func:`auto_budget` (a host-side result: a frozen dataclass, docs/architecture.md).

    Attributes:
        pos: chosen probe positions (n, 3).
        coverage: binary coverage of ``pos`` at the evaluation density.
        curve: (count, coverage) pairs in the order the search visited them.
        n_candidates: candidates considered (seeds + gap candidates).
        reached: whether the target was met.
        timings: seconds per phase.
        refine_status: the refiner's status message (``"ok"``, ``"reached max_steps"``, ``"objective
            became non-finite"``); ``None`` without a refiner.
        refined: whether the refined positions were kept (binary coverage did not drop).
    """

    pos: np.ndarray
    coverage: float
    curve: list
    n_candidates: int
    reached: bool
    timings: dict
    refine_status: str | None = None
    refined: bool = False


def _covered_area(vis_rows: np.ndarray, a: np.ndarray) -> float:
    return float((a * vis_rows.any(axis=0)).sum()) if len(vis_rows) else 0.0


def _row_gains(vis: np.ndarray, a: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """(vis & ~seen) @ a, a few rows at a time (no (rows × samples) float temporary)."""
    w = np.where(seen, 0.0, a)
    out = np.empty(len(vis))
    step = max(1, (1 << 22) // max(vis.shape[1], 1))
    for s in range(0, len(vis), step):
        out[s : s + step] = vis[s : s + step] @ w
    return out


def _greedy(
    vis: np.ndarray,
    a: np.ndarray,
    seen: np.ndarray,
    target_area: float,
    *,
    limit: int | None = None,
) -> list[int]:
    """Lazy greedy weighted set cover (Minoux 1978): rows of ``vis`` added until ``target_area`` is seen.

    Gains only shrink as ``seen`` grows (submodularity), so a stale gain is an upper bound: the top of a
    max-heap is re-evaluated and taken when it still beats the next stale gain. Same choices as the plain
    greedy (ties aside), with a handful of row evaluations per pick instead of all rows.

    Args:
        vis: (n_candidates, n) visibility rows.
        a: (n,) sample weights.
        seen: (n,) already seen samples; updated in place.
        target_area: stop once ``(a * seen).sum()`` reaches this.
        limit: pick at most this many.

    Returns:
        Picked row indices, in order.
    """
    picked: list[int] = []
    area = float(a[seen].sum())
    if area >= target_area or len(vis) == 0:
        return picked
    gain = _row_gains(vis, a, seen)
    heap = [(-g, i) for i, g in enumerate(gain) if g > 0]
    heapq.heapify(heap)
    while heap and area < target_area and (limit is None or len(picked) < limit):
        _, i = heapq.heappop(heap)
        g = float(a[vis[i] & ~seen].sum())
        if g <= 0:
            continue
        if heap and g < -heap[0][0]:
            heapq.heappush(heap, (-g, i))
            continue
        picked.append(i)
        seen |= vis[i]
        area = float(a[seen].sum())
    return picked


def _remove_redundant(rows: np.ndarray, a: np.ndarray, goal: float, curve: list) -> list[int]:
    """Drop probes (least unique area first) while the covered area stays ≥ ``goal``; kept row indices.

    Vectorised form of "try removing each probe, recompute coverage": removing probe j loses exactly its
    unique area (samples only j sees), so the least-unique probe is removable iff any is; per-sample
    counts and the unique owner of singly-seen samples are updated incrementally.
    """
    rows = rows.copy()
    k = len(rows)
    alive = np.ones(k, bool)
    count = rows.sum(axis=0, dtype=np.int32)
    covered = float(a[count > 0].sum())
    owner = np.full(rows.shape[1], -1, np.int64)
    one = count == 1
    owner[one] = rows[:, one].argmax(axis=0)
    while alive.sum() > 1:
        single = count == 1
        unique = np.bincount(owner[single], weights=a[single], minlength=k)
        unique[~alive] = np.inf
        j = int(np.argmin(unique))
        if not covered - unique[j] >= goal:
            break
        alive[j] = False
        cols = np.flatnonzero(rows[j])
        rows[j] = False
        count[cols] -= 1
        covered = float(a[count > 0].sum())
        now_one = cols[count[cols] == 1]
        if len(now_one):
            owner[now_one] = rows[:, now_one].argmax(axis=0)
        curve.append((int(alive.sum()), covered))
    return [int(i) for i in np.flatnonzero(alive)]


def _gap_candidates(
    problem: PlacementProblem, unseen: np.ndarray, n_new: int, rng: np.random.Generator
) -> np.ndarray:
    """Positions in front of unseen samples (farthest-point spread), feasible and in the box."""
    x = np.asarray(problem.position, np.float64)[unseen]
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


def _search_subset(cols: np.ndarray, m: int, x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``m`` of the samples ``cols``, spread in space: one random sample per occupied cell of a grid
    fine enough to hold ~m of them, then random ones to fill up (positions of ``cols`` are ``x``)."""
    if len(cols) <= m:
        return cols
    lo, hi = x.min(axis=0), x.max(axis=0)
    ext = np.maximum(hi - lo, 1e-12)
    cell = float(np.prod(ext) / m) ** (1.0 / 3.0)
    ijk = np.floor((x - lo) / cell).astype(np.int64)
    perm = rng.permutation(len(cols))
    key = (ijk[perm, 0] * 1_000_003 + ijk[perm, 1]) * 1_000_003 + ijk[perm, 2]
    _, first = np.unique(key, return_index=True)
    pick = perm[first]
    if len(pick) > m:
        pick = rng.choice(pick, m, replace=False)
    elif len(pick) < m:
        rest = np.setdiff1d(np.arange(len(cols)), pick)
        pick = np.concatenate([pick, rng.choice(rest, m - len(pick), replace=False)])
    return np.sort(cols[pick])


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
    search_samples: int | None = 32768,
) -> AutoResult:
    """Fewest probes reaching ``target`` coverage (module docstring); with ``max_probes``, the best
    ``max_probes`` probes when the budget binds first.

    A binding budget is filled from a pooled search: the greedy draws on the seeds first and gap candidates
    (in front of unseen samples) only join once the seeds add nothing, so under a small budget they would
    never compete — on Crytek Sponza 32 to 128 seed probes stall at 0.89 coverage while the full search
    covers everything with 199 probes, about 30 of them gap probes. So when the budgeted search misses the
    target, the full search runs too and the budget is chosen again, greedily, from its probes and the
    seeds; the better of the two choices is returned. Arguments as :func:`_search` (below).
    """
    kw = dict(
        target=target,
        max_rounds=max_rounds,
        gap_candidates=gap_candidates,
        caster=caster,
        search_samples=search_samples,
    )
    t0 = time.perf_counter()
    if candidates is None:
        candidates = np.concatenate([skeleton_seeds(problem), medial_axis_seeds(problem)])
    seeds_s = time.perf_counter() - t0
    refine = dict(refiner=refiner, refine_problem=refine_problem)
    k_budgeted, k_full, k_pooled = jax.random.split(key, 3)  # one key per search, never shared
    res = _search(problem, key=k_budgeted, candidates=candidates, max_probes=max_probes, **refine, **kw)
    res.timings["seeds_s"] = seeds_s
    if max_probes is None or res.reached:
        return res
    t0 = time.perf_counter()
    full = _search(problem, key=k_full, candidates=candidates, max_probes=None, **kw)
    pool = np.concatenate([full.pos, np.asarray(candidates, np.float32).reshape(-1, 3)])
    pooled = _search(problem, key=k_pooled, candidates=pool, max_probes=max_probes, **refine, **kw)
    best = pooled if pooled.coverage > res.coverage else res
    timings = {**best.timings, "seeds_s": seeds_s, "pooled_search_s": time.perf_counter() - t0}
    return dataclasses.replace(best, n_candidates=len(pool), timings=timings)


@dataclasses.dataclass(frozen=True, eq=False)
class _Coverable:
    """What one :func:`_search` measures coverage on: the coverable samples (every visibility row is over
    these columns), their areas, the target, and the phase timings it adds to."""

    problem: PlacementProblem
    caster: object
    cols: np.ndarray  # (m,) indices of the coverable samples in the problem
    a_all: np.ndarray  # (n_samples,) area, 0 where not coverable
    a: np.ndarray  # (m,) area of the coverable samples
    total: float
    target: float
    target_area: float
    timings: dict


def _check_search_options(target: float, search_samples: int | None) -> None:
    """Reject a target outside (0, 1] and a non-positive ``search_samples`` before any visibility work."""
    if not (0.0 < target <= 1.0):
        raise ConfigError(f"target coverage must be in (0, 1], got {target}")
    if search_samples is not None and search_samples < 1:
        raise ConfigError(f"search_samples must be positive or None, got {search_samples}")


def _feasible_candidates(problem: PlacementProblem, candidates: np.ndarray) -> np.ndarray:
    """The candidates (k, 3) float32 with at least the problem's SDF clearance (not inside geometry)."""
    cand = np.asarray(candidates, np.float32).reshape(-1, 3)
    return cand[probe_clearance(problem, cand) >= float(problem.clearance)]


def _coverable(problem: PlacementProblem, target: float, caster) -> _Coverable:
    """The coverable samples, their areas and the target area; timings start with ``visibility_s = 0``."""
    a_all = np.asarray(problem.area, np.float64) * np.asarray(problem.coverable)
    # Only coverable samples count: every row below is over these columns.
    cols = np.flatnonzero(a_all > 0)
    a = a_all[cols]
    total = a.sum()
    # Numerically "all": a target of 1 means every coverable sample.
    target_area = target * total * (1.0 - COVERAGE_RTOL)
    timings = {"visibility_s": 0.0}
    return _Coverable(problem, caster, cols, a_all, a, total, target, target_area, timings)


def _visibility(cov: _Coverable, p: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Binary visibility rows of probes ``p`` on coverable columns ``c``, timed into ``visibility_s``."""
    t1 = time.perf_counter()
    v = binary_visibility(cov.problem, p, caster=cov.caster, samples=cov.cols[c])
    cov.timings["visibility_s"] += time.perf_counter() - t1
    return v


def _coarse_pass(
    cov: _Coverable, cand: np.ndarray, search_samples: int | None, rng: np.random.Generator, limit: int | None
) -> tuple[list[int], bool]:
    """Step 2 on a spread subset of at most ``search_samples`` coverable samples (coarse-to-fine, module
    docstring): the lazy greedy picks (Minoux 1978) and whether the subset was every coverable sample."""
    sub = np.arange(len(cov.cols))
    if search_samples is not None and len(cov.cols) > search_samples:
        sub = _search_subset(sub, int(search_samples), np.asarray(cov.problem.position)[cov.cols], rng)
    v_sub = _visibility(cov, cand, sub)
    seen_sub = np.zeros(len(sub), bool)
    goal = cov.target * cov.a[sub].sum() * (1.0 - COVERAGE_RTOL)
    chosen = _greedy(v_sub, cov.a[sub], seen_sub, goal, limit=limit)
    return chosen, len(sub) == len(cov.cols)


def _add_from_candidates(
    cov: _Coverable, cand: np.ndarray, dead: np.ndarray, seen: np.ndarray, left: int | None
) -> list[int]:
    """Greedy picks among the live candidates scored on the unseen samples only; marks ``dead`` those that
    add nothing there and updates ``seen`` in place (both arrays)."""
    unseen = np.flatnonzero(~seen)
    rest = np.flatnonzero(~dead)
    if not len(rest):
        return []
    v_u = _visibility(cov, cand[rest], unseen)
    dead[rest[~v_u.any(axis=1)]] = True
    s_u = np.zeros(len(unseen), bool)
    picks = _greedy(v_u, cov.a[unseen], s_u, cov.target_area - cov.a[seen].sum(), limit=left)
    if picks:
        # what they add is known from the rows on the unseen samples; full rows come at the end
        seen[unseen] = s_u
    return [int(rest[i]) for i in picks]


def _gaps_in_front_of_unseen(
    cov: _Coverable, seen: np.ndarray, gap_candidates: int, rng: np.random.Generator
) -> np.ndarray:
    """Step 3, Wang's "adding where coverage is missing": gap candidates in front of unseen samples."""
    unseen_all = np.zeros(len(cov.a_all), bool)
    unseen_all[cov.cols[np.flatnonzero(~seen)]] = True
    return _gap_candidates(cov.problem, unseen_all, gap_candidates, rng)


def _fine_pass(
    cov: _Coverable,
    cand: np.ndarray,
    chosen: list[int],
    exact: bool,
    *,
    limit: int | None,
    max_rounds: int,
    gap_candidates: int,
    rng: np.random.Generator,
) -> tuple[np.ndarray, list[int], np.ndarray]:
    """Fine pass: the chosen probes at full density; candidates scored on what is still unseen, then gap
    candidates in front of unseen samples, until the target or the budget; (candidates, chosen, full rows)."""
    n = len(cov.cols)
    # Candidates that add nothing on the unseen samples never will (the unseen set only shrinks).
    dead = np.zeros(len(cand), bool)
    if exact:
        dead[:] = True
    rows = _visibility(cov, cand[chosen], np.arange(n)) if chosen else np.zeros((0, n), bool)
    seen = rows.any(axis=0) if len(rows) else np.zeros(n, bool)
    for _ in range(max_rounds + 1):
        if cov.a[seen].sum() >= cov.target_area or (limit is not None and len(chosen) >= limit):
            break
        dead[chosen] = True
        picks = _add_from_candidates(cov, cand, dead, seen, None if limit is None else limit - len(chosen))
        if picks:
            chosen += picks
            continue
        dead[:] = True
        gaps = _gaps_in_front_of_unseen(cov, seen, gap_candidates, rng)
        if len(gaps) == 0:
            break
        cand = np.concatenate([cand, gaps])
        dead = np.concatenate([dead, np.zeros(len(gaps), bool)])
    if len(chosen) > len(rows):
        rows = np.concatenate([rows, _visibility(cov, cand[chosen[len(rows) :]], np.arange(n))])
    return cand, chosen, rows


def _addition_curve(rows: np.ndarray, a: np.ndarray) -> list:
    """(count, covered area) after each greedy addition, in order, at full density."""
    curve: list = []
    acc = np.zeros(len(a), bool)
    for r in rows:
        acc |= r
        curve.append((len(curve) + 1, float(a[acc].sum())))
    return curve


def _refine_if_no_worse(
    cov: _Coverable,
    refiner: AbstractRefiner | None,
    refine_problem: PlacementProblem | None,
    pos: np.ndarray,
    rows: np.ndarray,
    coverage: float,
    key: jax.Array,
) -> tuple[np.ndarray, np.ndarray, float, str | None, bool]:
    """Step 4: refine the chosen set on the soft objective, kept only if that objective improved
    (:meth:`RefineResult.improved`: the function optimised is the one judged) and every probe keeps its
    clearance; (pos, rows, coverage, refine_status, refined). The binary coverage may then drop below
    the target: step 5 only removes probes while it stays at what was reached."""
    if refiner is None or not len(pos):
        return pos, rows, coverage, None, False
    t1 = time.perf_counter()
    res = refiner.refine(refine_problem or cov.problem, jnp.asarray(pos), key=key)
    refine_status, refined = res.status_message(), False
    new_pos = np.asarray(res.pos, np.float32)
    clear = np.all(probe_clearance(cov.problem, new_pos) >= float(cov.problem.clearance))
    if res.improved() and np.all(np.isfinite(new_pos)) and clear:
        # PERF: the full visibility rows only for a kept set (the acceptance no longer reads them)
        rows = _visibility(cov, new_pos, np.arange(len(cov.cols)))
        pos, coverage, refined = new_pos, _coverage_of(rows, cov.a), True
    cov.timings["refine_s"] = time.perf_counter() - t1
    return pos, rows, coverage, refine_status, refined


def _drop_redundant(
    cov: _Coverable, pos: np.ndarray, rows: np.ndarray, coverage: float, curve: list
) -> tuple[np.ndarray, np.ndarray]:
    """Step 5: drop probes (least unique area first) while the coverage stays at the target (or at what
    was reached); the removals extend ``curve``."""
    t1 = time.perf_counter()
    goal = min(coverage * cov.total, cov.target_area)
    keep = _remove_redundant(rows, cov.a, goal, curve) if len(rows) else []
    pos, rows = pos[keep], rows[keep]
    cov.timings["remove_s"] = time.perf_counter() - t1
    return pos, rows


def _search(
    problem: PlacementProblem,
    *,
    key: jax.Array,
    candidates: np.ndarray,
    target: float = 1.0,
    refiner: AbstractRefiner | None = None,
    refine_problem: PlacementProblem | None = None,
    max_rounds: int = 12,
    gap_candidates: int = 32,
    max_probes: int | None = None,
    caster=None,
    search_samples: int | None = 32768,
) -> AutoResult:
    """One greedy search: fewest probes reaching ``target`` coverage, or at most ``max_probes`` of them.

    Args:
        problem: the fitness model at the evaluation density (binary coverage is measured on it).
        key: PRNG key (gap-candidate spread, search subset and refinement).
        target: coverage share to reach, in (0, 1].
        refiner: refines the chosen set on ``refine_problem`` (soft objective); ``None``: no refinement.
        refine_problem: a (smaller) problem for the refiner; default ``problem``.
        candidates: start candidates (:func:`auto_budget`: default skeleton ∪ medial-axis seeds).
        max_rounds: rounds of gap candidates before giving up.
        gap_candidates: unseen samples used per round.
        max_probes: stop adding beyond this count.
        caster: optional exact ray caster for the binary visibility (e.g. ``make_caster(scene, "embree")``);
            default the SDF sphere tracer.
        search_samples: the first greedy pass scores the candidates on at most this many coverable samples
            (spread in space); the chosen probes are then checked, and completed, at full density. ``None``:
            every coverable sample from the start (module docstring, "coarse-to-fine").

    Raises:
        ConfigError: target outside (0, 1], or ``search_samples`` not positive.
    """
    _check_search_options(target, search_samples)
    cand = _feasible_candidates(problem, candidates)
    cov = _coverable(problem, target, caster)
    k_rng, k_refine = jax.random.split(key)  # the host generator's and the refiner's, apart
    rng = host_rng(k_rng)
    limit = None if max_probes is None else int(max_probes)
    t_greedy = time.perf_counter()
    # 1. coarse pass: every candidate scored on a spread subset of the coverable samples
    chosen, exact = _coarse_pass(cov, cand, search_samples, rng, limit)
    # 2. fine pass: the chosen probes at full density; candidates scored on what is still unseen, then
    #    gap candidates in front of unseen samples (Wang's "adding where coverage is missing")
    cand, chosen, rows = _fine_pass(
        cov, cand, chosen, exact, limit=limit, max_rounds=max_rounds, gap_candidates=gap_candidates, rng=rng
    )
    cov.timings["greedy_s"] = time.perf_counter() - t_greedy
    pos = cand[chosen]
    # the coverage-vs-count curve of the additions, at full density
    curve = _addition_curve(rows, cov.a)
    coverage = _coverage_of(rows, cov.a)
    # Refinement between adding and removing: keep it only if the binary coverage does not drop.
    pos, rows, coverage, refine_status, refined = _refine_if_no_worse(
        cov, refiner, refine_problem, pos, rows, coverage, k_refine
    )
    # Removal: drop probes (least unique area first) while the coverage stays at the target.
    pos, rows = _drop_redundant(cov, pos, rows, coverage, curve)
    curve = [(int(k), float(c / max(cov.total, 1e-300))) for k, c in curve]
    return AutoResult(
        pos=pos.astype(np.float32),
        coverage=_coverage_of(rows, cov.a),
        curve=curve,
        n_candidates=len(cand),
        reached=bool((cov.a * rows.any(axis=0)).sum() >= cov.target_area) if len(rows) else False,
        timings=cov.timings,
        refine_status=refine_status,
        refined=refined,
    )
