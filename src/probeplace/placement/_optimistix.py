"""Gradient refiners on the soft objectives through optimistix (BFGS, nonlinear CG, optax Adam).

Box constraints by reparametrisation, p = lo + (hi − lo)·σ(z) (every z is inside the box); free space by
the penalty λ·Σ relu(c − SDF(p))²/c² (:func:`penalty`), then :func:`push_out` projects any probe still
too near a surface. The loss −objective + penalty is minimised with the solver's own ``init``/``step``
inside a ``lax.scan`` so every step's objective is recorded (``history``); steps after the solver's
``terminate`` are frozen.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import optax
import optimistix as optx

from .._core import ConfigError
from ._refine import (
    MAX_STEPS,
    NONFINITE,
    OK,
    AbstractRefiner,
    RefineResult,
    _check_objective,
    _check_pos,
    objective_fn,
    penalty,
    push_out,
)

SOLVERS = ("bfgs", "nonlinear_cg", "adam")


class OptimistixRefiner(AbstractRefiner):
    """Minimise −objective + λ·penalty with an optimistix solver (module docstring).

    Attributes:
        solver: ``bfgs``, ``nonlinear_cg`` or ``adam`` (optax through ``optx.OptaxMinimiser``).
        objective: ``coverage`` or ``wang``.
        max_steps: solver steps (static).
        learning_rate: Adam step in the reparametrised z.
        penalty_weight: λ.
        rtol, atol: the solvers' Cauchy termination tolerances.
    """

    solver: str = eqx.field(static=True, default="bfgs")
    objective: str = eqx.field(static=True, default="coverage")
    max_steps: int = eqx.field(static=True, default=30)
    learning_rate: float = 0.05
    penalty_weight: float = 1.0
    rtol: float = 1e-5
    atol: float = 1e-7

    def __check_init__(self):
        _check_objective(self.objective)
        if self.solver not in SOLVERS:
            raise ConfigError(f"OptimistixRefiner.solver must be one of {SOLVERS}, got {self.solver!r}")
        if self.max_steps < 1:
            raise ConfigError(f"OptimistixRefiner.max_steps must be ≥ 1, got {self.max_steps}")

    def _solver(self):
        if self.solver == "bfgs":
            return optx.BFGS(rtol=self.rtol, atol=self.atol)
        if self.solver == "nonlinear_cg":
            return optx.NonlinearCG(rtol=self.rtol, atol=self.atol)
        return optx.OptaxMinimiser(optax.adam(self.learning_rate), rtol=self.rtol, atol=self.atol)

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
    to_pos = lambda z: lo[None] + span[None] * jax.nn.sigmoid(z)
    u = jnp.clip((pos - lo[None]) / span[None], eps, 1 - eps)
    z0 = jnp.log(u) - jnp.log1p(-u)

    def loss(z, args):
        p = to_pos(z)
        return -obj(p, active) + cfg.penalty_weight * penalty(problem, p), None

    solver = cfg._solver()
    f_struct = jax.ShapeDtypeStruct((), dtype)
    state = solver.init(loss, z0, None, {}, f_struct, None, frozenset())

    def body(carry, _):
        z, st, done = carry
        # optax's Adam bias correction raises a Python-float decay to an int32 count (decay**count), which
        # strict dtype promotion rejects; the objective itself stays float-clean under strict promotion.
        with jax.numpy_dtype_promotion("standard"):
            z_new, st_new, _ = solver.step(loss, z, None, {}, st, frozenset())
        term, _ = solver.terminate(loss, z_new, None, {}, st_new, frozenset())
        z = jnp.where(done, z, z_new)
        st = jax.tree.map(lambda a, b: jnp.where(done, a, b), st, st_new)
        return (z, st, done | term), obj(to_pos(z), active)

    (z, _, done), hist = jax.lax.scan(body, (z0, state, jnp.asarray(False)), None, length=cfg.max_steps)
    p = push_out(problem, to_pos(z))
    p = jnp.where(jnp.isfinite(p), p, pos)
    v = obj(p, active)
    v0 = obj(pos, active)
    better = v >= v0
    best = jnp.where(better, p, pos)
    status = jnp.where(~jnp.all(jnp.isfinite(hist)), NONFINITE, jnp.where(done, OK, MAX_STEPS)).astype(
        jnp.int32
    )
    return RefineResult(
        pos=best,
        value=jnp.maximum(v, v0),
        history=hist,
        status=status,
        n_accepted=jnp.asarray(cfg.max_steps, jnp.int32),
    )
