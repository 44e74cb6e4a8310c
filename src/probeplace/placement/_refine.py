"""The refiner interface and Wang et al. 2019 §3.3's support-cube ascent with Gibbs acceptance.

Every refiner takes a problem, start positions and a key, and returns a :class:`RefineResult` with the
best positions seen, a ``status`` (STYLE §5) and the objective after every iteration (``history``).
Objectives are *maximised*: ``"coverage"`` (union coverage) or ``"wang"`` (Eq. 1–2), both soft
(:mod:`._fitness`). Probes stay inside the placement box and at least ``clearance`` from surfaces.

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

Evaluating R(P′) only needs probe k's column: R for Eq. 1–2 is a sum over probes, and for the union
coverage the other probes' miss products are recomputed per update (O(n_probes·n_samples)).
"""

from __future__ import annotations

import abc
import math

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from .._core import ConfigError, ProbeplaceError
from ..geometry import sdf_value
from ._fitness import (
    PlacementProblem,
    coverage_from_columns,
    coverage_objective,
    dynamic_float,
    probe_column,
    probe_distance_term,
    wang_fitness,
)

OBJECTIVES = ("coverage", "wang")

# Status codes (STYLE §5).
OK, MAX_STEPS, NONFINITE = 0, 1, 2
STATUS_MESSAGES = {OK: "ok", MAX_STEPS: "reached max_steps", NONFINITE: "objective became non-finite"}


class RefineResult(eqx.Module):
    """What every refiner returns.

    Attributes:
        pos: best positions seen (world frame).
        value: objective at ``pos``.
        history: objective after each iteration (sweep / solver step), best-so-far not applied.
        status: OK, MAX_STEPS or NONFINITE.
        n_accepted: accepted moves (Gibbs) or steps taken (gradient refiners).
    """

    pos: Float[Array, "n_probes 3"]
    value: Float[Array, ""]
    history: Float[Array, " n_iter"]
    status: Int[Array, ""]
    n_accepted: Int[Array, ""]

    def status_message(self) -> str:
        return STATUS_MESSAGES.get(int(self.status), "unknown")


def objective_fn(problem: PlacementProblem, objective: str):
    """The soft objective to maximise, as a function of positions (and the active mask)."""
    if objective == "coverage":
        return lambda pos, active=None: coverage_objective(problem, pos, active)
    if objective == "wang":
        return lambda pos, active=None: wang_fitness(problem, pos, active)
    raise ConfigError(f"objective must be one of {OBJECTIVES}, got {objective!r}")


def feasible(problem: PlacementProblem, p: Float[Array, "3"]) -> Bool[Array, ""]:
    """Inside the box and at least the clearance away from surfaces."""
    inside = jnp.all((p >= problem.lo.astype(p.dtype)) & (p <= problem.hi.astype(p.dtype)))
    return inside & (sdf_value(problem.grid, p) >= problem.clearance.astype(p.dtype))


def penalty(problem: PlacementProblem, pos: Float[Array, "n_probes 3"]) -> Float[Array, ""]:
    """Σ relu(clearance − SDF)² / clearance²: zero in free space, growing into and inside geometry."""
    c = problem.clearance.astype(pos.dtype)
    d = jax.vmap(lambda p: sdf_value(problem.grid, p))(pos)
    return jnp.sum(jax.nn.relu(c - d) ** 2) / (c * c)


def push_out(problem: PlacementProblem, pos: Float[Array, "n_probes 3"], n_iter: int = 8) -> Array:
    """Move probes that are infeasible along the SDF gradient until they clear it (projection)."""
    c = problem.clearance.astype(pos.dtype)
    lo, hi = problem.lo.astype(pos.dtype), problem.hi.astype(pos.dtype)

    def one(p):
        def body(_, q):
            d, g = jax.value_and_grad(lambda x: sdf_value(problem.grid, x))(q)
            gn = jnp.linalg.norm(g)
            step = jnp.where((d < 1.5 * c) & (gn > 1e-6), (1.5 * c - d) / jnp.maximum(gn, 1e-6), 0.0)
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


def _check_objective(objective: str) -> None:
    if objective not in OBJECTIVES:
        raise ConfigError(f"objective must be one of {OBJECTIVES}, got {objective!r}")


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

    Attributes:
        objective: ``"coverage"`` or ``"wang"``.
        n_sweeps: sweeps over all probes (static); one history entry each.
        step: initial support-cube half-size γ, scene units; ``None``: box diagonal / 20.
        decay: γ multiplier per sweep.
        stochastic: stochastic direction sampling (else the best corner).
        gibbs: Gibbs acceptance ξ < (R′/R)^β (else accept only improvements).
        beta: β; 1 is Wang's rule (which accepts almost every small move: R′/R ≈ 1), larger values
            sample the sharper distribution R^β (simulated-annealing style) and climb faster.
    """

    objective: str = eqx.field(static=True, default="coverage")
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


@eqx.filter_jit
def _gibbs_run(cfg: GibbsRefiner, problem: PlacementProblem, pos, active, key, step0) -> RefineResult:
    dtype = pos.dtype
    n_probes = pos.shape[0]
    wang = cfg.objective == "wang"
    lo, hi = problem.lo.astype(dtype), problem.hi.astype(dtype)
    w = problem.weight.astype(dtype)
    w1, w2 = jnp.asarray(problem.config.w1, dtype), jnp.asarray(problem.config.w2, dtype)
    signs = jnp.asarray(_SIGNS, dtype)

    def column(p):
        col = probe_column(problem, p)
        d = probe_distance_term(problem, p, col.vis) if wang else jnp.zeros((), dtype)
        return col.vis, col.omega, d

    def per_probe(vis, omega, d):  # Wang: probe k's share r_k of Eq. 1
        return ((w1 * omega + w2 * d) * vis) @ w

    vis, omega, dbar = jax.vmap(column)(pos)

    def total(vis, omega, dbar):
        if wang:
            return jnp.sum(jnp.where(active, jax.vmap(per_probe)(vis, omega, dbar), 0.0))
        return coverage_from_columns(problem, vis, active)

    def value_with(k, vis, omega, dbar, v_k, o_k, d_k, others_miss):
        if wang:
            r = jax.vmap(per_probe)(vis, omega, dbar)
            return (
                jnp.sum(jnp.where(active, r, 0.0))
                - jnp.where(active[k], r[k], 0.0)
                + per_probe(v_k, o_k, d_k)
            )
        return jnp.sum(w * (1.0 - others_miss * (1.0 - v_k)))

    def update(k, carry):
        pos, vis, omega, dbar, r_cur, key, gamma, n_acc = carry
        key, k_dir, k_acc = jax.random.split(key, 3)
        p = pos[k]
        q = jnp.where(active[:, None] & (jnp.arange(n_probes) != k)[:, None], vis, 0.0)
        others_miss = jnp.prod(1.0 - q, axis=0)
        corners = jnp.clip(p[None] + gamma * signs, lo[None], hi[None])
        vc, oc, dc = jax.vmap(column)(corners)
        rc = jax.vmap(lambda a, b, c: value_with(k, vis, omega, dbar, a, b, c, others_miss))(vc, oc, dc)
        rc = jnp.where(jax.vmap(lambda c: feasible(problem, c))(corners), rc, 0.0)
        if cfg.stochastic:
            u = stochastic_direction(rc, k_dir)
            p_new = jnp.clip(p + gamma * u, lo, hi)
        else:
            p_new = corners[jnp.argmax(rc)]
        v_n, o_n, d_n = column(p_new)
        r_new = value_with(k, vis, omega, dbar, v_n, o_n, d_n, others_miss)
        r_new = jnp.where(feasible(problem, p_new), r_new, 0.0)
        xi = jax.random.uniform(k_acc, (), dtype)
        ratio = (r_new / jnp.maximum(r_cur, 1e-30)) ** jnp.asarray(cfg.beta, dtype)
        accept = (xi < ratio) if cfg.gibbs else (r_new > r_cur)
        accept = accept & active[k] & jnp.isfinite(r_new) & (r_new > 0)
        pos = pos.at[k].set(jnp.where(accept, p_new, p))
        vis = vis.at[k].set(jnp.where(accept, v_n, vis[k]))
        omega = omega.at[k].set(jnp.where(accept, o_n, omega[k]))
        dbar = dbar.at[k].set(jnp.where(accept, d_n, dbar[k]))
        r_cur = jnp.where(accept, r_new, r_cur)
        return pos, vis, omega, dbar, r_cur, key, gamma, n_acc + accept.astype(jnp.int32)

    def sweep(carry, _):
        pos, vis, omega, dbar, r_cur, key, gamma, n_acc, best_pos, best_r = carry
        pos, vis, omega, dbar, r_cur, key, gamma, n_acc = jax.lax.fori_loop(
            0, n_probes, update, (pos, vis, omega, dbar, r_cur, key, gamma, n_acc)
        )
        better = r_cur > best_r
        best_pos = jnp.where(better, pos, best_pos)
        best_r = jnp.where(better, r_cur, best_r)
        gamma = gamma * jnp.asarray(cfg.decay, dtype)
        return (pos, vis, omega, dbar, r_cur, key, gamma, n_acc, best_pos, best_r), r_cur

    r0 = total(vis, omega, dbar)
    init = (pos, vis, omega, dbar, r0, key, step0, jnp.zeros((), jnp.int32), pos, r0)
    out, hist = jax.lax.scan(sweep, init, None, length=cfg.n_sweeps)
    best_pos, best_r = out[8], out[9]
    status = jnp.where(jnp.all(jnp.isfinite(hist)), OK, NONFINITE).astype(jnp.int32)
    return RefineResult(pos=best_pos, value=best_r, history=hist, status=status, n_accepted=out[7])


def _library_refiner(module: str, cls: str, solver: str):
    """Factory of a refiner from an optional library's module (imported on first use: optimistix, optax and
    jaxopt are heavy, and most runs never refine)."""

    def make(objective: str, **kwargs) -> AbstractRefiner:
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


def get_refiner(name: str, *, objective: str = "coverage", **kwargs) -> AbstractRefiner:
    """Refiner by registry name (:data:`REFINERS`): ``gibbs``, ``ascent``, ``bfgs``, ``nonlinear_cg``,
    ``adam`` (optimistix / optax), ``projected_gradient``, ``lbfgsb`` (jaxopt)."""
    if name not in _REFINER_FACTORIES:
        raise ConfigError(f"unknown refiner {name!r}; choose one of {', '.join(REFINERS)}")
    return _REFINER_FACTORIES[name](objective, **kwargs)


def raise_if_failed(result: RefineResult) -> RefineResult:
    """``throw=True`` behaviour: a bad status becomes a ProbeplaceError with its message."""
    if int(result.status) == NONFINITE:
        raise ProbeplaceError(f"refinement failed: {result.status_message()}")
    return result
