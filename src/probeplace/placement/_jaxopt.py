"""jaxopt adapter (STYLE §11: jaxopt is unmaintained upstream, so it lives only here, pinned at 0.8.5).

Projected gradient with the box projection, or L-BFGS-B with box bounds, on −objective + λ·penalty in
position space, driven by :func:`gradient_loop` (one convergence rule in scene units for all gradient
refiners, see :mod:`._refine`; jaxopt's own ``tol`` on its error is not used); :func:`push_out` projects
probes still too near a surface. No jaxopt type leaves this module: the result is a :class:`RefineResult`.
"""

from __future__ import annotations

import warnings

import equinox as eqx
import jax
import jax.numpy as jnp

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

SOLVERS = ("projected_gradient", "lbfgsb")


def _jaxopt():
    with warnings.catch_warnings():  # "JAXopt is no longer maintained" on import
        warnings.simplefilter("ignore", DeprecationWarning)
        import jaxopt
    return jaxopt


class JaxoptRefiner(AbstractRefiner):
    """Box-constrained refinement with jaxopt (module docstring).

    Attributes:
        solver: ``projected_gradient`` or ``lbfgsb``.
        objective: a name of ``OBJECTIVES`` or a callable ``(pos, active) -> scalar``.
        max_steps: iterations at most (static).
        stepsize: projected-gradient fixed step (scaled variables); ``None``: jaxopt's
            backtracking line search.
        acceleration: FISTA momentum for projected gradient. Off by default: FISTA is not monotone and
            its momentum keeps the steps from shrinking, so no step test fires (Cornell, 8 skeleton probes:
            200 steps, still climbing ~10⁻⁵ per step; without it, converged in 57 steps).
        penalty_weight: λ.
        xtol_voxels, ftol, patience, stall: the convergence rule (as ``OptimistixRefiner``).
    """

    solver: str = eqx.field(static=True, default="lbfgsb")
    objective: Objective = eqx.field(static=True, default="coverage")
    max_steps: int = eqx.field(static=True, default=300)
    stepsize: float | None = eqx.field(static=True, default=None)
    acceleration: bool = eqx.field(static=True, default=False)
    penalty_weight: float = eqx.field(default=1.0, converter=dynamic_float)
    xtol_voxels: float = eqx.field(default=0.1, converter=dynamic_float)
    ftol: float = eqx.field(default=1e-5, converter=dynamic_float)
    patience: int = eqx.field(static=True, default=2)
    stall: int = eqx.field(static=True, default=10)

    def __check_init__(self):
        _check_objective(self.objective)
        if self.solver not in SOLVERS:
            raise ConfigError(f"JaxoptRefiner.solver must be one of {SOLVERS}, got {self.solver!r}")
        if self.max_steps < 1:
            raise ConfigError(f"JaxoptRefiner.max_steps must be ≥ 1, got {self.max_steps}")
        if not (self.xtol_voxels > 0 and self.ftol > 0):
            raise ConfigError("JaxoptRefiner.xtol_voxels and ftol must be positive")

    def refine(self, problem, pos, *, key, active=None):
        del key
        _check_pos(pos)
        active = jnp.ones(pos.shape[0], bool) if active is None else active
        return _run(self, problem, pos, active)


@eqx.filter_jit
def _run(cfg: JaxoptRefiner, problem, pos, active) -> RefineResult:
    jaxopt = _jaxopt()
    dtype = pos.dtype
    lo = jnp.broadcast_to(problem.lo.astype(dtype), pos.shape)
    hi = jnp.broadcast_to(problem.hi.astype(dtype), pos.shape)
    obj = objective_fn(problem, cfg.objective)
    lam = jnp.asarray(cfg.penalty_weight, dtype)
    # Scale positions by the diagonal so the solvers see O(1) variables.
    scale = problem.diag.astype(dtype)

    def raw_loss(y):
        p = y * scale
        return -obj(p, active) + lam * penalty(problem, p)

    bounds = (lo / scale, hi / scale)
    y0 = jnp.clip(pos, lo, hi) / scale
    # Divided by its largest partial derivative at the start (as in _optimistix): an O(1) gradient, so
    # the line searches' unit initial steps are on the problem's scale.
    g0 = jnp.max(jnp.abs(jax.grad(raw_loss)(y0)))
    inv_scale = 1.0 / jnp.where(jnp.isfinite(g0) & (g0 > 0), g0, 1.0)

    def loss(y):
        return raw_loss(y) * inv_scale

    if cfg.solver == "lbfgsb":
        solver = jaxopt.LBFGSB(fun=loss, maxiter=cfg.max_steps)
    else:
        step = 0.0 if cfg.stepsize is None else cfg.stepsize  # 0: line search
        solver = jaxopt.ProjectedGradient(
            fun=loss,
            projection=jaxopt.projection.projection_box,
            maxiter=cfg.max_steps,
            stepsize=step,
            acceleration=cfg.acceleration,
        )
    state = solver.init_state(y0, bounds)

    def step(carry):
        y, st = solver.update(*carry, bounds)  # an OptStep: back to the plain tuple the loop carries
        return y, st

    return gradient_loop(
        problem,
        cfg.objective,
        step,
        (y0, state),
        lambda carry: jnp.clip(carry[0] * scale, lo, hi),
        pos,
        active,
        max_steps=cfg.max_steps,
        xtol_voxels=cfg.xtol_voxels,
        ftol=cfg.ftol,
        patience=cfg.patience,
        stall=cfg.stall,
    )
