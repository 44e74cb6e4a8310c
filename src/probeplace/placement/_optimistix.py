"""Gradient refiners on the soft objectives through optimistix (BFGS, nonlinear CG, optax Adam).

Box constraints by reparametrisation for BFGS and CG, p = lo + (hi − lo)·σ(z) (every z is inside the box),
and by projection for Adam (z = the position in box units, clipped to [0, 1] after each step: a fixed-step
method needs exponentially many steps to approach a face through the saturating σ); free space by
the penalty λ·Σ relu(m·c − SDF(p))²/c² (:func:`penalty`), then :func:`push_out` projects any probe still
too near a surface. The loss −objective + penalty is minimised with the solver's own ``init``/``step``
inside :func:`gradient_loop` (a ``lax.while_loop``), which records every step's objective (``history``)
and stops on one convergence rule in scene units for all gradient refiners (see :mod:`._refine`). The
solvers' own Cauchy tests (in z, relative to |z|) are not used.

Adam's fixed step never shrinks, so its iterates oscillate at ~``learning_rate`` around an optimum and
no step test can fire; optax's ``reduce_on_plateau`` halves the rate when the loss has not improved for
``patience`` steps — the usual way to let a first-order method settle — so Adam converges too.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import optax
import optimistix as optx

from .._core import ConfigError
from ._fitness import dynamic_float
from ._refine import (
    AbstractRefiner,
    Objective,
    RefineResult,
    _check_objective,
    _check_pos,
    gradient_loop,
    objective_fn,
    penalty,
)

SOLVERS = ("bfgs", "nonlinear_cg", "adam")


class OptimistixRefiner(AbstractRefiner):
    """Minimise −objective + λ·penalty with an optimistix solver (module docstring).

    Attributes:
        solver: ``bfgs``, ``nonlinear_cg`` or ``adam`` (optax through ``optx.OptaxMinimiser``).
        objective: a name of ``OBJECTIVES`` or a callable ``(pos, active) -> scalar``.
        max_steps: solver steps at most (static).
        learning_rate: Adam's initial step, a fraction of the box side (halved on plateaus).
        penalty_weight: λ.
        xtol_voxels: convergence: every probe moved at most this many SDF voxels per step (a tenth of a
            voxel: below the SDF's own resolution, the soft visibility cannot tell the positions apart).
        ftol: convergence: the objective changed by at most ``ftol``·|f| per step (10⁻⁵: a sample of a
            1 500-sample problem weighs ~7·10⁻⁴ of the coverage).
        patience: accepted steps in a row that must meet both tolerances (static).
        stall: steps in a row without an accepted move that count as converged (static).
    """

    solver: str = eqx.field(static=True, default="bfgs")
    objective: Objective = eqx.field(static=True, default="coverage")
    max_steps: int = eqx.field(static=True, default=300)
    learning_rate: float = eqx.field(default=0.02, converter=dynamic_float)
    penalty_weight: float = eqx.field(default=1.0, converter=dynamic_float)
    xtol_voxels: float = eqx.field(default=0.1, converter=dynamic_float)
    ftol: float = eqx.field(default=1e-5, converter=dynamic_float)
    patience: int = eqx.field(static=True, default=2)
    stall: int = eqx.field(static=True, default=10)

    def __check_init__(self):
        _check_objective(self.objective)
        if self.solver not in SOLVERS:
            raise ConfigError(f"OptimistixRefiner.solver must be one of {SOLVERS}, got {self.solver!r}")
        if self.max_steps < 1:
            raise ConfigError(f"OptimistixRefiner.max_steps must be ≥ 1, got {self.max_steps}")
        if not (self.xtol_voxels > 0 and self.ftol > 0):
            raise ConfigError("OptimistixRefiner.xtol_voxels and ftol must be positive")

    def _solver(self, dtype):
        # The libraries' Cauchy tests are switched off (zero tolerances); gradient_loop decides.
        if self.solver == "bfgs":
            return optx.BFGS(rtol=0.0, atol=0.0)
        if self.solver == "nonlinear_cg":
            return optx.NonlinearCG(rtol=0.0, atol=0.0)
        lr = jnp.asarray(self.learning_rate, dtype)
        # any decrease is progress (optax wants a positive tolerance; rtol misjudges a negative loss)
        plateau = optax.contrib.reduce_on_plateau(factor=0.5, patience=5, rtol=0.0, atol=1e-12)
        return optx.OptaxMinimiser(optax.chain(optax.adam(lr), plateau), rtol=0.0, atol=0.0)

    def refine(self, problem, pos, *, key, active=None):
        del key  # deterministic
        _check_pos(pos)
        active = jnp.ones(pos.shape[0], bool) if active is None else active
        return _run(self, problem, pos, active)


@eqx.filter_jit
def _run(cfg: OptimistixRefiner, problem, pos, active) -> RefineResult:
    dtype = pos.dtype
    lo, hi = problem.lo.astype(dtype), problem.hi.astype(dtype)
    span = hi - lo
    eps = jnp.asarray(1e-4, dtype)
    obj = objective_fn(problem, cfg.objective)
    lam = jnp.asarray(cfg.penalty_weight, dtype)
    u = jnp.clip((pos - lo[None]) / span[None], eps, 1 - eps)
    projected = cfg.solver == "adam"
    if projected:  # z = the position in box units, projected back into [0, 1] after every step
        to_pos = lambda z: lo[None] + span[None] * jnp.clip(z, 0.0, 1.0)
        z0 = u
    else:
        to_pos = lambda z: lo[None] + span[None] * jax.nn.sigmoid(z)
        z0 = jnp.log(u) - jnp.log1p(-u)

    def raw_loss(z):
        p = to_pos(z)
        return -obj(p, active) + lam * penalty(problem, p)

    # The loss is divided by its largest partial derivative at the start, so the first unit step moves
    # the steepest coordinate by one logit (~a tenth of the box) whatever the objective's scale: nonlinear
    # CG's backtracking line search starts at step 1 and only shrinks it, so on the raw soft coverage
    # (|∂f/∂z| ~ 10⁻²) it crawled at ~10⁻⁵ per step for 200 steps. BFGS's first (identity-Hessian) step
    # gets the same scale; Adam is invariant to it. Convergence is judged on the objective itself.
    g0 = jnp.max(jnp.abs(jax.grad(raw_loss)(z0)))
    inv_scale = 1.0 / jnp.where(jnp.isfinite(g0) & (g0 > 0), g0, 1.0)

    def loss(z, args):
        return raw_loss(z) * inv_scale, None

    solver = cfg._solver(dtype)
    f_struct = jax.ShapeDtypeStruct((), dtype)
    # optax's Adam bias correction raises a Python-float decay to an int32 count (decay**count), which
    # strict dtype promotion rejects; the objective itself stays float-clean under strict promotion.
    with jax.numpy_dtype_promotion("standard"):
        state = solver.init(loss, z0, None, {}, f_struct, None, frozenset())

    def step(carry):
        z, st = carry
        with jax.numpy_dtype_promotion("standard"):
            z, st, _ = solver.step(loss, z, None, {}, st, frozenset())
        return (jnp.clip(z, 0.0, 1.0) if projected else z), st

    return gradient_loop(
        problem,
        cfg.objective,
        step,
        (z0, state),
        lambda carry: to_pos(carry[0]),
        pos,
        active,
        max_steps=cfg.max_steps,
        xtol_voxels=cfg.xtol_voxels,
        ftol=cfg.ftol,
        patience=cfg.patience,
        stall=cfg.stall,
    )
