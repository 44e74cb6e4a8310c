"""The refiner interface and Wang et al. 2019 §3.3's support-cube ascent with Gibbs acceptance.

Every refiner takes a problem, start positions and a key, and returns a :class:`RefineResult` with the
best positions seen, the objective there (``value``) and at the start (``start_value``, the same
function), a ``status`` (STYLE §5) and the objective after every iteration (``history``). Objectives are
*maximised*: ``"coverage"`` (union coverage), ``"wang"`` (Eq. 1–2) or ``"shading"`` (a shading-quality
proxy), all soft (:mod:`._fitness`), or any callable ``(pos, active) -> scalar`` (toy objectives with a
known optimum in the tests; :func:`make_box_problem` gives such an objective a box and a free space).
Probes stay inside the placement box and at least ``clearance`` from surfaces. A caller keeps the
refined set iff :meth:`RefineResult.improved` (finite and above ``start_value``): the function optimised
is the function judged.

Gradient refiners (:mod:`._optimistix`, :mod:`._jaxopt`) share :func:`gradient_loop`: one convergence
rule in scene units, a Cauchy test on consecutive accepted iterates, max |Δp| ≤ ``xtol_voxels``·h and
|Δf| ≤ ``ftol``·|f| on ``patience`` accepted steps in a row (or ``stall`` rejected line-search trials in a
row: no ascent at the step scale). The libraries' own tests measure the step in their variables (a
logit per coordinate under the sigmoid box map, rtol 10⁻⁵·|z|, i.e. 10⁻³ scene units on Cornell), which
none reached in 30 steps while the soft coverage was still climbing by ~10⁻⁴ per step.

:class:`GibbsRefiner` is Wang §3.3, probes updated in sequence. For probe k at p:

* the 8 support probes on the corners of a cube of half-size γ around p are evaluated (R(P′ₛ), P′ₛ the
  set with pₖ replaced by corner s; an infeasible corner — in a solid or too near a surface — scores 0);
* deterministic direction: the best corner; *stochastic direction sampling*: along x, a linear model
  f(x) = ax + b through each of the 4 x-edges' end values is sampled by inversion, F(x) = (a/2)x² + bx
  normalised on [0, 1], x = (−b + √(b² + 2aξ(a/2 + b)))/a; then along y between the pairs of those 4
  points (their values from the linear models), then along z between the last two — a point u of the
  cube (Fig. 6), and the proposal p′ = p + γu;
* *Gibbs acceptance*: p′ replaces p when ξ < R(P′)/R(P) (ξ uniform on [0, 1]);
* γ starts at ``step`` (default: the box diagonal / 20) and shrinks by ``decay`` per sweep, damping the
  oscillation Wang describes.

Evaluating R(P′) only re-marches probe k's column (:func:`objective_parts`): the objective is then
recombined from the stored columns (O(n_probes·n_samples) arithmetic, no visibility march). The best
state is tracked after every move, and ``value`` is recomputed at the returned positions.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from ..._core import ConfigError, ProbeplaceError
from ...geometry import SDFGrid, sdf_value
from ..fitness import (
    FitnessConfig,
    PlacementProblem,
    coverage_from_columns,
    dynamic_float,
    probe_column,
    probe_distance_term,
    shading_column,
    shading_from_columns,
    wang_from_columns,
)

OBJECTIVES = ("coverage", "wang", "shading")

#: An objective: a name of :data:`OBJECTIVES` or a callable ``(pos (n_probes, 3), active (n_probes,)) ->
#: scalar`` to maximise (hashable: it is a static field of the refiner, so one compilation per callable).
Objective = str | Callable

# Status codes (STYLE §5).
OK, MAX_STEPS, NONFINITE = 0, 1, 2
STATUS_MESSAGES = {OK: "ok", MAX_STEPS: "reached max_steps", NONFINITE: "objective became non-finite"}


class RefineResult(eqx.Module):
    """What every refiner returns.

    Attributes:
        pos: best positions seen (world frame): the start, a feasible iterate or the projected end point.
        value: the refiner's objective at ``pos`` (the function it optimises, evaluated there).
        start_value: the same objective at the start positions.
        history: objective after each iteration (sweep / solver step), best-so-far not applied; the
            gradient refiners repeat their last value after they stop.
        status: OK, MAX_STEPS or NONFINITE.
        n_accepted: accepted moves (Gibbs) or solver steps taken (gradient refiners).
    """

    pos: Float[Array, "n_probes 3"]
    value: Float[Array, ""]
    start_value: Float[Array, ""]
    history: Float[Array, " n_iter"]
    status: Int[Array, ""]
    n_accepted: Int[Array, ""]

    def status_message(self) -> str:
        return STATUS_MESSAGES.get(int(self.status), "unknown")

    def improved(self) -> bool:
        """The acceptance rule: ``value`` is finite and above ``start_value`` (host bool)."""
        v = float(self.value)
        return math.isfinite(v) and v > float(self.start_value)

    @property
    def fitness_gain(self) -> float:
        """``value / start_value`` on the refiner's own objective (≥ 1; ``nan`` when the start is 0)."""
        v0 = float(self.start_value)
        return float(self.value) / v0 if v0 != 0 else math.nan


def objective_parts(problem: PlacementProblem, objective: Objective) -> tuple[Callable, Callable]:
    """(column_fn, combine_fn): the objective is ``combine_fn(vmap(column_fn)(pos), active)``.

    ``column_fn(p)`` is what one probe contributes (its soft visibility column, …), a pytree; the Gibbs
    refiner recomputes only probe k's column per move. A callable objective's "column" is the position.
    """
    _check_objective(objective)
    if callable(objective):
        return (lambda p: p), objective
    if objective == "coverage":
        return (
            lambda p: probe_column(problem, p).vis,
            lambda vis, active: coverage_from_columns(problem, vis, active),
        )
    if objective == "wang":

        def wang_column(p):
            col = probe_column(problem, p)
            return col.vis, col.omega, probe_distance_term(problem, p, col.vis)

        return wang_column, lambda c, active: wang_from_columns(problem, c[0], c[1], c[2], active)
    return (
        lambda p: shading_column(problem, p),
        lambda q, active: shading_from_columns(problem, q, active),
    )


def objective_fn(problem: PlacementProblem, objective: Objective):
    """The objective to maximise as ``f(pos, active=None)``: a name of :data:`OBJECTIVES` (the soft
    ``coverage_objective``, ``wang_fitness``, ``shading_objective`` of :mod:`._fitness`, same operations)
    or a callable ``(pos, active) -> scalar``, returned as is apart from the default mask."""
    column, combine = objective_parts(problem, objective)

    def f(pos, active=None):
        active = jnp.ones(pos.shape[0], bool) if active is None else active
        return combine(jax.vmap(column)(pos), active)

    return f


def feasible(problem: PlacementProblem, p: Float[Array, "3"]) -> Bool[Array, ""]:
    """Inside the box and at least the clearance away from surfaces."""
    inside = jnp.all((p >= problem.lo.astype(p.dtype)) & (p <= problem.hi.astype(p.dtype)))
    return inside & (sdf_value(problem.grid, p) >= problem.clearance.astype(p.dtype))


#: The penalty starts at this multiple of the clearance: a penalised optimum sits slightly inside its
#: threshold (the objective's pull balances the penalty's), so a threshold a quarter clearance out leaves
#: it feasible — and untouched by :func:`push_out` — instead of projected 1.5 clearances out.
PENALTY_MARGIN = 1.25


def penalty(problem: PlacementProblem, pos: Float[Array, "n_probes 3"]) -> Float[Array, ""]:
    """Σ relu(m·clearance − SDF)² / clearance² (m = :data:`PENALTY_MARGIN`): zero in free space, growing
    into and inside geometry."""
    c = problem.clearance.astype(pos.dtype)
    d = jax.vmap(lambda p: sdf_value(problem.grid, p))(pos)
    return jnp.sum(jax.nn.relu(PENALTY_MARGIN * c - d) ** 2) / (c * c)


def push_out(problem: PlacementProblem, pos: Float[Array, "n_probes 3"], n_iter: int = 8) -> Array:
    """Move infeasible probes (SDF < clearance) along the SDF gradient to 1.5 clearances (projection);
    feasible probes stay where they are."""
    c = problem.clearance.astype(pos.dtype)
    lo, hi = problem.lo.astype(pos.dtype), problem.hi.astype(pos.dtype)

    def one(p):
        bad = sdf_value(problem.grid, p) < c

        def body(_, q):
            d, g = jax.value_and_grad(lambda x: sdf_value(problem.grid, x))(q)
            gn = jnp.linalg.norm(g)
            move = bad & (d < 1.5 * c) & (gn > 1e-6)
            step = jnp.where(move, (1.5 * c - d) / jnp.maximum(gn, 1e-6), 0.0)
            return jnp.clip(q + step * g / jnp.maximum(gn, 1e-6), lo, hi)  # all rank 1

        return jax.lax.fori_loop(0, n_iter, body, p)

    return jax.vmap(one)(pos)


class AbstractRefiner(eqx.Module):
    """Improves probe positions for a soft objective; see the module docstring."""

    @abc.abstractmethod
    def refine(
        self,
        problem: PlacementProblem,
        pos: Float[Array, "n_probes 3"],
        *,
        key: jax.Array,
        active: Bool[Array, " n_probes"] | None = None,
    ) -> RefineResult:
        """Refine ``pos`` (float32 or float64); returns the best positions seen."""


def _check_objective(objective: Objective) -> None:
    if callable(objective):
        return
    if objective not in OBJECTIVES:
        raise ConfigError(f"objective must be one of {OBJECTIVES} or a callable, got {objective!r}")


# Corner s of the support cube: bit 0 → x, bit 1 → y, bit 2 → z (0 = −1, 1 = +1).
_SIGNS = tuple(tuple(2 * ((s >> a) & 1) - 1 for a in range(3)) for s in range(8))


def _sample_linear(fa: Array, fb: Array, xi: Array) -> Array:
    """x ∈ [0, 1] with density ∝ f(x) = fa + (fb − fa)x (inversion, Wang §3.3); uniform if f ≡ 0."""
    a = fb - fa
    b = fa
    total = a / 2.0 + b
    ok = total > 1e-30
    small = jnp.abs(a) <= 1e-6 * jnp.maximum(jnp.abs(b), 1e-30)
    disc = jnp.maximum(b * b + 2.0 * a * xi * total, 0.0)
    a_safe = jnp.where(small, 1.0, a)
    x = jnp.where(small, xi, (-b + jnp.sqrt(disc)) / a_safe)
    return jnp.where(ok, jnp.clip(x, 0.0, 1.0), xi)


def stochastic_direction(values: Float[Array, "8"], key: jax.Array) -> Float[Array, "3"]:
    """A point of the support cube [−1, 1]³ sampled from the 8 corner values (Wang §3.3, Fig. 6)."""
    dtype = values.dtype
    xi = jax.random.uniform(key, (7,), dtype)
    signs = jnp.asarray(_SIGNS, dtype)
    # x: four edges, one per (y, z); corners 2j and 2j+1 differ in x only.
    fa, fb = values[0::2], values[1::2]
    tx = _sample_linear(fa, fb, xi[:4])
    px = signs[0::2] + tx[:, None] * (signs[1::2] - signs[0::2])
    vx = fa + (fb - fa) * tx
    # y: pairs (y=−1, y=+1) for z = −1 (edges 0, 1) and z = +1 (edges 2, 3).
    ga, gb = vx[0::2], vx[1::2]
    ty = _sample_linear(ga, gb, xi[4:6])
    py = px[0::2] + ty[:, None] * (px[1::2] - px[0::2])
    vy = ga + (gb - ga) * ty
    # z: the last pair.
    tz = _sample_linear(vy[0], vy[1], xi[6])
    return py[0] + tz * (py[1] - py[0])


class GibbsRefiner(AbstractRefiner):
    """Wang §3.3: support-cube ascent, stochastic directions, Gibbs acceptance (module docstring).

    A fixed-sweep method: its status is OK when it finishes finite. The acceptance ratio R′/R needs a
    positive objective (the named ones are ≥ 0; an infeasible corner scores 0).

    Attributes:
        objective: a name of :data:`OBJECTIVES` or a callable ``(pos, active) -> scalar`` (> 0).
        n_sweeps: sweeps over all probes (static); one history entry each.
        step: initial support-cube half-size γ, scene units; ``None``: box diagonal / 20.
        decay: γ multiplier per sweep.
        stochastic: stochastic direction sampling (else the best corner).
        gibbs: Gibbs acceptance ξ < (R′/R)^β (else accept only improvements).
        beta: β; 1 is Wang's rule (which accepts almost every small move: R′/R ≈ 1), larger values
            sample the sharper distribution R^β (simulated-annealing style) and climb faster.
    """

    objective: Objective = eqx.field(static=True, default="coverage")
    n_sweeps: int = eqx.field(static=True, default=12)
    step: float | None = eqx.field(default=None, converter=dynamic_float)
    decay: float = eqx.field(default=0.85, converter=dynamic_float)
    stochastic: bool = eqx.field(static=True, default=True)
    gibbs: bool = eqx.field(static=True, default=True)
    beta: float = eqx.field(default=1.0, converter=dynamic_float)

    def __check_init__(self):
        _check_objective(self.objective)
        if not (math.isfinite(self.beta) and self.beta > 0):
            raise ConfigError(f"GibbsRefiner.beta must be positive, got {self.beta}")
        if self.n_sweeps < 1:
            raise ConfigError(f"GibbsRefiner.n_sweeps must be ≥ 1, got {self.n_sweeps}")
        if not (0 < self.decay <= 1):
            raise ConfigError(f"GibbsRefiner.decay must be in (0, 1], got {self.decay}")
        if self.step is not None and not (math.isfinite(self.step) and self.step > 0):
            raise ConfigError(f"GibbsRefiner.step must be positive, got {self.step}")

    def refine(self, problem, pos, *, key, active=None):
        _check_pos(pos)
        active = jnp.ones(pos.shape[0], bool) if active is None else active
        step0 = problem.diag.astype(pos.dtype) / 20.0 if self.step is None else self.step
        return _gibbs_run(self, problem, pos, active, key, jnp.asarray(step0, pos.dtype))


def _check_pos(pos) -> None:
    if pos.ndim != 2 or pos.shape[1] != 3 or pos.shape[0] < 1:
        raise ConfigError(f"probe positions must have shape (n_probes ≥ 1, 3), got {tuple(pos.shape)}")


def _set_row(tree, k, row):
    return jax.tree.map(lambda a, r: a.at[k].set(r), tree, row)


def _where_row(tree, k, accept, row):
    return jax.tree.map(lambda a, r: a.at[k].set(jnp.where(accept, r, a[k])), tree, row)


@eqx.filter_jit
def _gibbs_run(cfg: GibbsRefiner, problem: PlacementProblem, pos, active, key, step0) -> RefineResult:
    dtype = pos.dtype
    n_probes = pos.shape[0]
    lo, hi = problem.lo.astype(dtype), problem.hi.astype(dtype)
    signs = jnp.asarray(_SIGNS, dtype)
    column, combine = objective_parts(problem, cfg.objective)

    def value_with(cols, k, col_k):  # the objective with probe k's column replaced (only k re-marched)
        return combine(_set_row(cols, k, col_k), active)

    def update(k, carry):
        pos, cols, r_cur, key, gamma, n_acc, best_pos, best_r = carry
        key, k_dir, k_acc = jax.random.split(key, 3)
        p = pos[k]
        corners = jnp.clip(p[None] + gamma * signs, lo[None], hi[None])
        rc = jax.vmap(lambda c: value_with(cols, k, c))(jax.vmap(column)(corners))
        rc = jnp.where(jax.vmap(lambda c: feasible(problem, c))(corners), rc, 0.0)
        if cfg.stochastic:
            u = stochastic_direction(rc, k_dir)
            p_new = jnp.clip(p + gamma * u, lo, hi)
        else:
            p_new = corners[jnp.argmax(rc)]
        col_new = column(p_new)
        r_new = value_with(cols, k, col_new)
        r_new = jnp.where(feasible(problem, p_new), r_new, 0.0)
        xi = jax.random.uniform(k_acc, (), dtype)
        ratio = (r_new / jnp.maximum(r_cur, 1e-30)) ** jnp.asarray(cfg.beta, dtype)
        accept = (xi < ratio) if cfg.gibbs else (r_new > r_cur)
        accept = accept & active[k] & jnp.isfinite(r_new) & (r_new > 0)
        pos = pos.at[k].set(jnp.where(accept, p_new, p))
        cols = _where_row(cols, k, accept, col_new)
        r_cur = jnp.where(accept, r_new, r_cur)
        # the best state is tracked after every move (not only at sweep ends): an improving move that a
        # later downhill Gibbs move undoes is still kept
        better = r_cur > best_r
        best_pos = jnp.where(better, pos, best_pos)
        best_r = jnp.where(better, r_cur, best_r)
        return pos, cols, r_cur, key, gamma, n_acc + accept.astype(jnp.int32), best_pos, best_r

    def sweep(carry, _):
        pos, cols, r_cur, key, gamma, n_acc, best_pos, best_r = carry
        pos, cols, r_cur, key, gamma, n_acc, best_pos, best_r = jax.lax.fori_loop(0, n_probes, update, carry)
        gamma = gamma * jnp.asarray(cfg.decay, dtype)
        return (pos, cols, r_cur, key, gamma, n_acc, best_pos, best_r), r_cur

    cols0 = jax.vmap(column)(pos)
    r0 = combine(cols0, active)
    init = (pos, cols0, r0, key, step0, jnp.zeros((), jnp.int32), pos, r0)
    out, hist = jax.lax.scan(sweep, init, None, length=cfg.n_sweeps)
    # ``value`` is recomputed at the returned positions by the objective itself (the running value is
    # the same function, accumulated move by move); the start wins ties and float-rounding losses.
    best_pos, v = out[6], combine(jax.vmap(column)(out[6]), active)
    keep = jnp.isfinite(v) & (v > r0)
    status = jnp.where(jnp.all(jnp.isfinite(hist)), OK, NONFINITE).astype(jnp.int32)
    return RefineResult(
        pos=jnp.where(keep, best_pos, pos),
        value=jnp.where(keep, v, r0),
        start_value=r0,
        history=hist,
        status=status,
        n_accepted=out[5],
    )


class AbstractGradientRefiner(AbstractRefiner):
    """What the gradient refiners (``_optimistix``, ``_jaxopt``) share: the solver name, the objective,
    the step cap, the clearance penalty's weight λ and :func:`gradient_loop`'s convergence test.

    Attributes:
        solver: the solver's name (each module's ``SOLVERS``).
        objective: a name of ``OBJECTIVES`` or a callable ``(pos, active) -> scalar``.
        max_steps: solver steps at most (static).
        penalty_weight: λ.
        xtol_voxels: convergence: every probe moved at most this many SDF voxels per step (a tenth of a
            voxel: below the SDF's own resolution, the soft visibility cannot tell the positions apart).
        ftol: convergence: the objective changed by at most ``ftol``·|f| per step (10⁻⁵: a sample of a
            1 500-sample problem weighs ~7·10⁻⁴ of the coverage).
        patience: accepted steps in a row that must meet both tolerances (static).
        stall: steps in a row without an accepted move that count as converged (static).
    """

    solver: eqx.AbstractVar[str]
    objective: Objective = eqx.field(static=True, default="coverage")
    max_steps: int = eqx.field(static=True, default=300)
    penalty_weight: float = eqx.field(default=1.0, converter=dynamic_float)
    xtol_voxels: float = eqx.field(default=0.1, converter=dynamic_float)
    ftol: float = eqx.field(default=1e-5, converter=dynamic_float)
    patience: int = eqx.field(static=True, default=2)
    stall: int = eqx.field(static=True, default=10)

    def check_settings(self, solvers: tuple[str, ...]) -> None:
        """ConfigError naming the class and the bad setting (called by the subclasses' checks)."""
        name = type(self).__name__
        _check_objective(self.objective)
        if self.solver not in solvers:
            raise ConfigError(f"{name}.solver must be one of {solvers}, got {self.solver!r}")
        if self.max_steps < 1:
            raise ConfigError(f"{name}.max_steps must be ≥ 1, got {self.max_steps}")
        if not (self.xtol_voxels > 0 and self.ftol > 0):
            raise ConfigError(f"{name}.xtol_voxels and ftol must be positive")

    def run_loop(self, problem, step_fn, carry0, pos_fn, start, active) -> RefineResult:
        """:func:`gradient_loop` with these settings."""
        return gradient_loop(
            problem,
            self.objective,
            step_fn,
            carry0,
            pos_fn,
            start,
            active,
            max_steps=self.max_steps,
            xtol_voxels=self.xtol_voxels,
            ftol=self.ftol,
            patience=self.patience,
            stall=self.stall,
        )


def normalised_loss(cfg: AbstractGradientRefiner, problem, active, to_pos: Callable, z0) -> Callable:
    """−objective + λ·penalty at ``to_pos(z)``, divided by its largest partial derivative at ``z0``.

    Why: the first unit step then moves the steepest coordinate by one unit of ``z`` whatever the
    objective's scale — nonlinear CG's and L-BFGS-B's backtracking line searches start at step 1 and only
    shrink it, so on the raw soft coverage (|∂f/∂z| ~ 10⁻²) they crawled at ~10⁻⁵ per step for 200 steps.
    BFGS's first (identity-Hessian) step gets the same scale; Adam is invariant to it. Convergence is
    judged on the objective itself (:func:`gradient_loop`).
    """
    obj = objective_fn(problem, cfg.objective)
    lam = jnp.asarray(cfg.penalty_weight, z0.dtype)

    def raw_loss(z):
        p = to_pos(z)
        return -obj(p, active) + lam * penalty(problem, p)

    g0 = jnp.max(jnp.abs(jax.grad(raw_loss)(z0)))
    inv_scale = 1.0 / jnp.where(jnp.isfinite(g0) & (g0 > 0), g0, 1.0)
    return lambda z: raw_loss(z) * inv_scale


def gradient_loop(
    problem: PlacementProblem,
    objective: Objective,
    step_fn: Callable,
    carry0,
    pos_fn: Callable,
    start: Float[Array, "n_probes 3"],
    active: Bool[Array, " n_probes"],
    *,
    max_steps: int,
    xtol_voxels,
    ftol,
    patience: int,
    stall: int,
) -> RefineResult:
    """Drive a gradient solver (``carry = step_fn(carry)``, positions ``pos_fn(carry)``) to convergence.

    Converged (OK) when ``patience`` accepted steps in a row (steps that moved a probe) moved every probe
    by at most ``xtol_voxels`` SDF voxels and changed the objective by at most ``ftol``·|f|, or when
    ``stall`` steps in a row moved nothing (every line-search trial rejected: no ascent found at the
    step scale); MAX_STEPS after ``max_steps`` steps; NONFINITE when the objective stops being finite.
    The result is the best of the start, the best feasible iterate and the end point projected by
    :func:`push_out` (when feasible), with the objective evaluated there.
    """
    dtype = start.dtype
    obj = objective_fn(problem, objective)
    xtol = jnp.asarray(xtol_voxels, dtype) * problem.voxel.astype(dtype)
    ftol = jnp.asarray(ftol, dtype)
    all_feasible = lambda p: jnp.all(jax.vmap(lambda q: feasible(problem, q))(p))
    v_start = obj(start, active)
    p0 = pos_fn(carry0)
    f0 = obj(p0, active)
    zero = jnp.zeros((), jnp.int32)
    hist0 = jnp.zeros((max_steps,), dtype)

    def cond(st):
        i, _, _, _, _, _, done, bad, _, _, _ = st
        return (i < max_steps) & ~done & ~bad

    def body(st):
        i, carry, p_prev, f_prev, n_small, n_stall, done, bad, hist, best_p, best_f = st
        carry = step_fn(carry)
        p = pos_fn(carry)
        f = obj(p, active)
        moved = jnp.any(p != p_prev)
        small = (jnp.max(jnp.abs(p - p_prev)) <= xtol) & (
            jnp.abs(f - f_prev) <= ftol * jnp.maximum(jnp.abs(f), jnp.abs(f_prev))
        )
        n_small = jnp.where(moved, jnp.where(small, n_small + 1, 0), n_small)
        n_stall = jnp.where(moved, 0, n_stall + 1)
        done = (n_small >= patience) | (n_stall >= stall)
        bad = ~jnp.isfinite(f) | ~jnp.all(jnp.isfinite(p))
        better = ~bad & all_feasible(p) & (f > best_f)
        best_p = jnp.where(better, p, best_p)
        best_f = jnp.where(better, f, best_f)
        return i + 1, carry, p, f, n_small, n_stall, done, bad, hist.at[i].set(f), best_p, best_f

    init = (zero, carry0, p0, f0, zero, zero, jnp.asarray(False), jnp.asarray(False), hist0, start, v_start)
    n, _, p_last, f_last, _, _, done, bad, hist, best_p, best_f = jax.lax.while_loop(cond, body, init)
    hist = jnp.where(jnp.arange(max_steps, dtype=jnp.int32) < n, hist, f_last)
    # the end point, probes still inside the penalty's reach projected out
    p_end = push_out(problem, jnp.where(jnp.isfinite(p_last), p_last, start))
    f_end = obj(p_end, active)
    end_better = jnp.isfinite(f_end) & all_feasible(p_end) & (f_end > best_f)
    best_p = jnp.where(end_better, p_end, best_p)
    best_f = jnp.where(end_better, f_end, best_f)
    status = jnp.where(bad, NONFINITE, jnp.where(done, OK, MAX_STEPS)).astype(jnp.int32)
    return RefineResult(
        pos=best_p, value=best_f, start_value=v_start, history=hist, status=status, n_accepted=n
    )


def make_box_problem(
    lo,
    hi,
    *,
    sdf_fn: Callable | None = None,
    n_cells: int = 16,
    samples: tuple | None = None,
    config: FitnessConfig | None = None,
) -> PlacementProblem:
    """A :class:`PlacementProblem` without a scene: the box [lo, hi] and an analytic free space.

    For refiners on toy objectives (a callable objective needs only the box, the SDF and its voxel for
    feasibility and tolerances) and for closed-form checks of the named objectives.

    Args:
        lo, hi: the placement box corners, world frame.
        sdf_fn: signed distance of a point (NumPy (…, 3) → (…)), sampled on an ``n_cells``³ lattice over
            the box (trilinear: exact for planes); ``None``: free space (1000 voxels everywhere).
        n_cells: lattice cells per axis (the voxel h is the box's longest side / n_cells).
        samples: ``(position (n, 3), normal (n, 3), area (n,))`` surface samples, all coverable;
            ``None``: one sample at the box centre.
        config: fitness parameters.
    """
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    h = float(np.max(hi - lo)) / n_cells
    axes = [lo[a] + h * np.arange(int(np.ceil((hi[a] - lo[a]) / h)) + 1) for a in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1)
    values = np.full(pts.shape[:-1], 1000.0 * h) if sdf_fn is None else np.asarray(sdf_fn(pts), np.float64)
    grid = SDFGrid(
        values=jnp.asarray(values, jnp.float32),
        origin=jnp.asarray(lo, jnp.float32),
        voxel_size=jnp.asarray(h, jnp.float32),
    )
    if samples is None:
        samples = (((lo + hi) / 2)[None], np.array([[0.0, 0.0, 1.0]]), np.ones(1))
    x, nrm, area = (np.asarray(a, np.float64) for a in samples)
    return PlacementProblem(
        grid=grid,
        position=jnp.asarray(x, jnp.float32),
        normal=jnp.asarray(nrm, jnp.float32),
        weight=jnp.asarray(area / area.sum(), jnp.float32),
        area=jnp.asarray(area, jnp.float32),
        coverable=jnp.ones(len(area), bool),
        lo=jnp.asarray(lo, jnp.float32),
        hi=jnp.asarray(hi, jnp.float32),
        diag=jnp.asarray(np.linalg.norm(hi - lo), jnp.float32),
        config=FitnessConfig() if config is None else config,
    )


def _library_refiner(module: str, cls: str, solver: str):
    """Factory of a refiner from an optional library's module (imported on first use: optimistix, optax and
    jaxopt are heavy, and most runs never refine)."""

    def make(objective: Objective, **kwargs) -> AbstractRefiner:
        import importlib

        refiner = getattr(importlib.import_module(module, __package__), cls)
        return refiner(solver=solver, objective=objective, **kwargs)

    return make


#: The one list of refiners: registry name → factory(objective, **kwargs). Its order is the CLI's and the
#: reports'. ``ascent`` is Gibbs' best-corner move without the Gibbs sampler.
_REFINER_FACTORIES = {
    "gibbs": lambda objective, **kw: GibbsRefiner(objective=objective, **kw),
    "ascent": lambda objective, **kw: GibbsRefiner(objective=objective, stochastic=False, gibbs=False, **kw),
    **{s: _library_refiner("._optimistix", "OptimistixRefiner", s) for s in ("bfgs", "nonlinear_cg", "adam")},
    **{s: _library_refiner("._jaxopt", "JaxoptRefiner", s) for s in ("projected_gradient", "lbfgsb")},
}
REFINERS = tuple(_REFINER_FACTORIES)


def get_refiner(name: str, *, objective: Objective = "coverage", **kwargs) -> AbstractRefiner:
    """Refiner by registry name (:data:`REFINERS`): ``gibbs``, ``ascent``, ``bfgs``, ``nonlinear_cg``,
    ``adam`` (optimistix / optax), ``projected_gradient``, ``lbfgsb`` (jaxopt); ``objective`` a name of
    :data:`OBJECTIVES` or a callable ``(pos, active) -> scalar`` to maximise."""
    if name not in _REFINER_FACTORIES:
        raise ConfigError(f"unknown refiner {name!r}; choose one of {', '.join(REFINERS)}")
    return _REFINER_FACTORIES[name](objective, **kwargs)


def raise_if_failed(result: RefineResult) -> RefineResult:
    """``throw=True`` behaviour: a bad status becomes a ProbeplaceError with its message."""
    if int(result.status) == NONFINITE:
        raise ProbeplaceError(f"refinement failed: {result.status_message()}")
    return result
