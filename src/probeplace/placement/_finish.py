"""The common end of every placement method: valid space, the exact budget, coverage and the refiner.

Every method hands its positions to :func:`finish_lattice` (the lattice methods and any new method) or,
with its own search and refinement, to :func:`make_usable` and :func:`coverage_context` (the skeleton
methods), so that all of them

1. keep only *usable* probes: relocated out of geometry to the clearance and into the placement region,
   the rest dropped (``_valid``, DDGI relocation / Unity APV's virtual offset);
2. return exactly the probe count asked for (``_budget``: trim least unique coverage, fill farthest);
3. report binary coverage measured the same way — one coverage problem per seed (the ``"coverage"``
   random stream), one caster — so coverages compare like for like across methods;
4. refine, when asked, and keep the refined set only when the refiner's own objective improved
   (:meth:`RefineResult.improved`: the objective optimised is the one judged) and the set stays usable.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from .._core import ConfigError, ProbeSet, Scene, scene_box, stream
from ..geometry import AbstractRayCaster
from ._registry import PlaceRequest, PlaceResult
from .fitness import (
    CoverageDetail,
    FitnessConfig,
    PlacementProblem,
    binary_coverage,
    binary_visibility,
    coverage_counts,
    make_problem,
)
from .refine import get_refiner
from .space import (
    Region,
    default_clearance,
    fit_to_budget,
    make_valid,
    reachable_space,
    valid_candidates,
    view_positions,
)


@dataclass(frozen=True, eq=False)
class CoverageContext:
    """How every method measures binary coverage for one request: the problem (surface samples of the
    ``"coverage"`` stream of the seed, the request's fitness config) and the visibility caster."""

    problem: PlacementProblem
    caster: AbstractRayCaster | None

    def visibility(self, pos) -> np.ndarray:
        """Binary visibility (n_probes, n_samples) of ``pos``."""
        return binary_visibility(self.problem, np.asarray(pos, np.float32), caster=self.caster)

    def coverage(self, pos) -> float:
        """Share of the coverable area seen by at least one of ``pos``."""
        return binary_coverage(self.problem, self.visibility(pos)) if len(pos) else 0.0

    @property
    def area(self) -> np.ndarray:
        """Each sample's coverable area (0 where not coverable)."""
        return np.asarray(self.problem.area, np.float64) * np.asarray(self.problem.coverable)

    @property
    def visibility_name(self) -> str:
        return "sdf" if self.caster is None else type(self.caster).__name__

    def measure(self, pos) -> tuple[float, CoverageDetail]:
        """(coverage, :class:`CoverageDetail`) of ``pos`` from one visibility pass."""
        detail = coverage_counts(self.problem, self.visibility(pos))
        return (detail.coverage if len(detail.seen) else 0.0), detail


def coverage_detail(cov: CoverageContext, pos) -> CoverageDetail:
    """Each probe's part in the coverage of ``pos`` as ``cov`` measures it (:func:`coverage_context`: the
    run's coverage samples and caster, so the counts add up to the coverage the placement reported): per
    probe the coverable samples it sees and those only it sees (counts and area shares), and the coverable
    samples no probe sees (indices, positions, normals): one visibility pass
    (:meth:`CoverageContext.measure`).
    """
    return cov.measure(np.asarray(pos, np.float32).reshape(-1, 3))[1]


def result_coverage_detail(result: PlaceResult) -> CoverageDetail | None:
    """Each probe's part in a placement's coverage: the detail the method measured from the final set's
    visibility, else one visibility pass with the result's coverage context (None without one)."""
    if result.coverage_detail is not None:
        return result.coverage_detail
    if result.coverage_context is None:
        return None
    active = np.asarray(result.probes.active, bool)
    return coverage_detail(result.coverage_context, np.asarray(result.probes.pos_world)[active])


def coverage_context(scene: Scene, request: PlaceRequest, sdf) -> CoverageContext:
    """The coverage problem and caster of ``request`` (module docstring, step 3)."""
    problem = make_problem(
        scene,
        key=stream(request.seed, "coverage"),
        grid=sdf,
        config=request.config,
        reach_clearance=request.clearance,
    )
    return CoverageContext(problem, search_caster(scene, request.caster))


def search_caster(scene: Scene, caster: str | AbstractRayCaster | None):
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


def make_usable(
    scene: Scene,
    request: PlaceRequest,
    pos,
    *,
    sdf,
    cov: CoverageContext,
    spare: np.ndarray | None = None,
    valid: bool = True,
    relocated: np.ndarray | None = None,
) -> tuple[np.ndarray, dict]:
    """Steps 1–2 of the module docstring: ``pos`` made valid, then trimmed or filled to the budget (an
    integer budget; ``"auto"`` keeps the count). ``spare``: the method's unchosen candidates, offered to
    the fill before the valid-space lattice. ``valid=False`` (the grid's ``inside="keep"``, kept to show
    the classic failure) skips step 1. ``relocated``: (n,) bool, probes of ``pos`` the method itself
    already moved out of geometry (the grid's ``inside="relocate"``). Returns (positions, record for the
    metadata). The record names the returned probes that moved or were added (:func:`_which_record`)."""
    pos = np.asarray(pos, np.float32).reshape(-1, 3)
    clearance, region, reach, lo, hi = valid_settings(scene, request, sdf, with_reach=valid)
    record: dict = {}
    moved_out = np.zeros(len(pos), bool) if relocated is None else np.asarray(relocated, bool).copy()
    if moved_out.shape != (len(pos),):
        raise ValueError(f"relocated must be ({len(pos)},), got {moved_out.shape}")
    projected = np.zeros(len(pos), bool)
    if valid:
        v = make_valid(sdf, pos, clearance=clearance, region=region, lo=lo, hi=hi, reach=reach)
        keep = ~np.asarray(v.dropped)
        pos = np.asarray(v.pos, np.float32)[keep]
        moved_out = (moved_out | np.asarray(v.relocated, bool))[keep]
        projected = np.asarray(v.projected, bool)[keep]
        record["valid_space"] = v.record()
    if request.budget == "auto":
        return pos, {**record, **_which_record(moved_out, projected, np.zeros(0, np.int64))}

    def pool(n_needed: int) -> np.ndarray:
        extra = _usable_spare(spare, sdf, clearance, region, lo, hi, reach) if valid else np.zeros((0, 3))
        spacing = float(np.prod(hi - lo) / max(8 * (n_needed + len(pos)), 1)) ** (1 / 3)
        for _ in range(6):  # refine the lattice until the valid space offers enough points
            lattice = valid_candidates(sdf, lo, hi, clearance, region if valid else None, spacing, reach)
            if len(extra) + len(lattice) >= n_needed:
                break
            spacing /= 2
        return np.concatenate([np.asarray(extra, np.float32).reshape(-1, 3), lattice.astype(np.float32)])

    fit = fit_to_budget(pos, int(request.budget), visibility=cov.visibility, area=cov.area, pool_fn=pool)
    if fit.short:
        raise ConfigError(
            f"budget {request.budget}: the valid space (clearance {clearance:.4g}) holds only "
            f"{len(fit.pos)} probes at the finest fill lattice; lower the budget or the clearance"
        )
    record["budget_fit"] = fit.record()
    kept = np.arange(len(pos)) if fit.kept is None else fit.kept
    pad = len(fit.pos) - len(kept)  # the filled rows, after the kept ones
    moved_out = np.concatenate([moved_out[kept], np.zeros(pad, bool)])
    projected = np.concatenate([projected[kept], np.zeros(pad, bool)])
    return fit.pos, {**record, **_which_record(moved_out, projected, fit.filled)}


def _which_record(relocated: np.ndarray, projected: np.ndarray, filled: np.ndarray) -> dict:
    """Which of the returned probes (indices into the final set, the order of ``probes.json``) were
    relocated out of geometry, projected into the placement region, or filled to the budget. A refined set
    keeps its indices: the lists name where each probe came from before the refiner moved it."""
    return {
        "relocated_probes": np.flatnonzero(relocated).tolist(),
        "projected_probes": np.flatnonzero(projected).tolist(),
        "filled_probes": np.asarray(filled, np.int64).tolist(),
    }


def valid_settings(scene: Scene, request: PlaceRequest, sdf, *, with_reach: bool = True):
    """What step 1 checks for ``request``: (clearance, region, reachable space or None, lo, hi); the
    reachable space is not built when ``with_reach`` is false (step 1 skipped)."""
    lo, hi = (np.asarray(v, np.float64) for v in scene_box(scene))
    clearance = default_clearance(scene, sdf) if request.clearance is None else float(request.clearance)
    reach = reachable_space(sdf, clearance, view_positions(scene)) if with_reach else None
    return clearance, Region.from_config(request.region), reach, lo, hi


def usable_count(scene: Scene, request: PlaceRequest, pos, *, sdf) -> int:
    """How many of ``pos`` step 1 keeps (valid space, reach included): the count a lattice method compares
    with its budget when it picks a lattice."""
    pos = np.asarray(pos, np.float32).reshape(-1, 3)
    if not len(pos):
        return 0
    clearance, region, reach, lo, hi = valid_settings(scene, request, sdf)
    v = make_valid(sdf, pos, clearance=clearance, region=region, lo=lo, hi=hi, reach=reach)
    return int((~v.dropped).sum())


def _usable_spare(spare, sdf, clearance, region, lo, hi, reach) -> np.ndarray:
    """The spare candidates that are already valid (no relocation: they are offered, not owed)."""
    if spare is None or not len(spare):
        return np.zeros((0, 3), np.float32)
    v = make_valid(
        sdf, np.asarray(spare, np.float32), clearance=clearance, region=region, lo=lo, hi=hi, reach=reach
    )
    ok = ~np.asarray(v.moved) & ~np.asarray(v.dropped)
    return np.asarray(spare, np.float32).reshape(-1, 3)[ok]


def refine_if_improved(scene: Scene, request: PlaceRequest, pos: np.ndarray, *, sdf, still_usable):
    """Step 4: the request's refiner on its own (smaller) problem from the ``"refine-samples"`` stream;
    the refined set is kept when its objective improved and ``still_usable(new)`` holds.
    Returns (pos, status, refined, record)."""
    problem = refine_problem(scene, request, sdf)
    refiner = get_refiner(request.refiner, objective=request.objective)
    out = refiner.refine(problem, jnp.asarray(pos), key=stream(request.seed, "refine"))
    new = np.asarray(out.pos, np.float32)
    record = {"refine_objective_before": float(out.start_value), "refine_objective_after": float(out.value)}
    if out.improved() and np.all(np.isfinite(new)) and still_usable(new):
        return new, out.status_message(), True, record
    return pos, out.status_message(), False, record


def refine_problem(scene: Scene, request: PlaceRequest, sdf) -> PlacementProblem:
    """The refiner's (smaller) problem: ``n_opt_samples`` samples, 16 march steps unless a config is given."""
    config = FitnessConfig(n_steps=16) if request.config is None else request.config
    key = stream(request.seed, "refine-samples")
    return make_problem(
        scene,
        key=key,
        grid=sdf,
        n_samples=request.n_opt_samples,
        config=config,
        reach_clearance=request.clearance,
    )


def probe_set(pos, method: str) -> ProbeSet:
    return ProbeSet(pos_world=jnp.asarray(pos), active=jnp.ones(len(pos), bool), method=method)


def finish_lattice(
    scene: Scene,
    request: PlaceRequest,
    method: str,
    pos,
    *,
    sdf,
    timings: dict,
    t_all: float,
    info: dict,
    spare: np.ndarray | None = None,
    valid: bool = True,
    relocated: np.ndarray | None = None,
) -> PlaceResult:
    """Steps 1–4 of the module docstring for a method that lays its positions without a search (Vardis
    2021 §4's "global optimiser as a last step" is step 4). ``relocated``: as :func:`make_usable`'s."""
    t0 = time.perf_counter()
    cov = coverage_context(scene, request, sdf)
    pos, record = make_usable(
        scene, request, pos, sdf=sdf, cov=cov, spare=spare, valid=valid, relocated=relocated
    )
    coverage, detail = cov.measure(pos)
    timings["coverage_s"] = time.perf_counter() - t0
    refined, status = False, None
    if request.refiner is not None and len(pos):
        t0 = time.perf_counter()
        n = len(pos)

        def still_usable(new):
            again, _ = make_usable(scene, request, new, sdf=sdf, cov=cov, valid=valid)
            return len(again) == n and np.allclose(again, new)

        pos, status, refined, rec = refine_if_improved(
            scene, request, pos, sdf=sdf, still_usable=still_usable
        )
        record.update(rec)
        if refined:
            coverage, detail = cov.measure(pos)
        timings["refine_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_all
    return PlaceResult(
        probes=probe_set(pos, method),
        method=method,
        request=request,
        coverage=coverage,
        visibility=cov.visibility_name,
        timings=timings,
        refine_status=status,
        refined=refined,
        info={**info, **record},
        coverage_detail=detail,
        coverage_context=cov,
    )
