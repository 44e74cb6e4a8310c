"""jaxopt adapter (STYLE §11: jaxopt is unmaintained upstream, so it lives only here, pinned at 0.8.5).

Projected gradient with the box projection, or L-BFGS-B with box bounds, on −objective + λ·penalty in
position space; :func:`push_out` projects probes still too near a surface. No jaxopt type leaves this
module: the result is a :class:`RefineResult`.
"""

from __future__ import annotations

import warnings

import equinox as eqx
import jax
import jax.numpy as jnp

from .._core import ConfigError
from ._refine import (
    MAX_STEPS,
    NONFINITE,
    AbstractRefiner,
    RefineResult,
    _check_objective,
    _check_pos,
    objective_fn,
    penalty,
    push_out,
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
        objective: ``coverage`` or ``wang``.
        max_steps: iterations (static).
        stepsize: projected-gradient fixed step (scaled variables); ``None``: jaxopt's
            backtracking line search.
        penalty_weight: λ.
    """

    solver: str = eqx.field(static=True, default="lbfgsb")
    objective: str = eqx.field(static=True, default="coverage")
    max_steps: int = eqx.field(static=True, default=30)
    stepsize: float | None = None
    penalty_weight: float = 1.0

    def __check_init__(self):
        _check_objective(self.objective)
        if self.solver not in SOLVERS:
            raise ConfigError(f"JaxoptRefiner.solver must be one of {SOLVERS}, got {self.solver!r}")
        if self.max_steps < 1:
            raise ConfigError(f"JaxoptRefiner.max_steps must be ≥ 1, got {self.max_steps}")

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
    # Scale positions by the diagonal so the solvers see O(1) variables.
    scale = problem.diag.astype(dtype)

    def loss(y):
        p = y * scale
        return -obj(p, active) + cfg.penalty_weight * penalty(problem, p)

    bounds = (lo / scale, hi / scale)
    if cfg.solver == "lbfgsb":
        solver = jaxopt.LBFGSB(fun=loss, maxiter=cfg.max_steps)
    else:
        step = 0.0 if cfg.stepsize is None else cfg.stepsize  # 0: line search
        solver = jaxopt.ProjectedGradient(
            fun=loss, projection=jaxopt.projection.projection_box, maxiter=cfg.max_steps, stepsize=step
        )
    y0 = pos / scale
    state = solver.init_state(y0, bounds)

    def body(carry, _):
        y, st = carry
        y, st = solver.update(y, st, bounds)
        return (y, st), obj(y * scale, active)

    (y, _), hist = jax.lax.scan(body, (y0, state), None, length=cfg.max_steps)
    p = push_out(problem, jnp.clip(y * scale, lo, hi))
    v, v0 = obj(p, active), obj(pos, active)
    best = jnp.where(v >= v0, p, pos)
    status = jnp.where(jnp.all(jnp.isfinite(hist)), MAX_STEPS, NONFINITE).astype(jnp.int32)
    return RefineResult(
        pos=best,
        value=jnp.maximum(v, v0),
        history=hist,
        status=status,
        n_accepted=jnp.asarray(cfg.max_steps, jnp.int32),
    )
