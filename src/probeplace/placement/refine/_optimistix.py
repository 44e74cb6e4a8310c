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

from ..fitness import dynamic_float
from ._refine import AbstractGradientRefiner, RefineResult, _check_pos, normalised_loss

SOLVERS = ("bfgs", "nonlinear_cg", "adam")


class OptimistixRefiner(AbstractGradientRefiner):
    """Minimise −objective + λ·penalty with an optimistix solver (module docstring).

    Attributes:
        solver: ``bfgs``, ``nonlinear_cg`` or ``adam`` (optax through ``optx.OptaxMinimiser``).
        learning_rate: Adam's initial step, a fraction of the box side (halved on plateaus).

    The objective, step cap, penalty and convergence settings: :class:`AbstractGradientRefiner`.
    """

    solver: str = eqx.field(static=True, default="bfgs")
    learning_rate: float = eqx.field(default=0.02, converter=dynamic_float)

    def __check_init__(self):
        self.check_settings(SOLVERS)

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
    u = jnp.clip((pos - lo[None]) / span[None], eps, 1 - eps)
    projected = cfg.solver == "adam"
    if projected:  # z = the position in box units, projected back into [0, 1] after every step
        to_pos = lambda z: lo[None] + span[None] * jnp.clip(z, 0.0, 1.0)
        z0 = u
    else:
        to_pos = lambda z: lo[None] + span[None] * jax.nn.sigmoid(z)
        z0 = jnp.log(u) - jnp.log1p(-u)

    raw = normalised_loss(cfg, problem, active, to_pos, z0)

    def loss(z, args):
        return raw(z), None

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

    return cfg.run_loop(problem, step, (z0, state), lambda carry: to_pos(carry[0]), pos, active)
