"""Stop a Gauss-Newton-type least-squares solve once it has stopped paying: `StallStop`.

Why: optimistix's own test (step and loss change both below ``rtol`` / ``atol``, the Cauchy criterion) does not fire
while the parameters still drift along a flat valley of the loss.  Measured (session 26, the 30 000-sample benchmark
record of issue 18, the Gaussian-Preisach cascade): the loss reached 0.092811 by step 20 and 0.092771 at the
300-step cap, a gain of 0.6 in log-likelihood over 280 steps (about 28 s of the default fit's critical path); the
EUPI cascade's solves converged by their own test at 100-128 steps with nothing left to gain after about 60-95.

The rule: stop when the last ``window`` steps raised the Gaussian profile log-likelihood of the residuals,
``n / 2 * log(SSE_before / SSE_now)`` with ``n`` the number of weighted residuals, by less than ``min_gain``.  On that
scale 0.5 is one standard error of one parameter, so a gain of 0.1 over 20 steps is statistically nothing; a fit far
from the noise floor (model misfit) is judged on its own residual scale.
"""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import optimistix as optx

__all__ = ["StallStop", "STALL_WINDOW", "STALL_MIN_GAIN"]

#: Steps over which the log-likelihood gain is measured.
STALL_WINDOW = 20
#: Least log-likelihood gain over `STALL_WINDOW` steps for the solve to go on.
STALL_MIN_GAIN = 0.1


class _StallState(eqx.Module):
    inner: Any
    sse: jax.Array  # (window + 1,) the accepted SSE after each of the last window + 1 steps, oldest first
    stalled: jax.Array


class StallStop(optx.AbstractLeastSquaresSolver):
    """Wraps a Gauss-Newton-type solver (`optimistix.LevenbergMarquardt`, `optimistix.GaussNewton`: it reads their
    state's residual at the last accepted step) and also stops it when the last ``window`` steps gained less than
    ``min_gain`` in log-likelihood (module docstring).  The iterates are the wrapped solver's, so a solve that stops
    early returns exactly the point the unwrapped solve passed through at that step."""

    solver: optx.AbstractLeastSquaresSolver
    window: int = eqx.field(static=True, default=STALL_WINDOW)
    min_gain: float = eqx.field(static=True, default=STALL_MIN_GAIN)

    def __check_init__(self):
        if not (isinstance(self.window, int) and self.window >= 1):
            raise ValueError(f"StallStop: window must be an integer >= 1, got {self.window!r}")
        if not self.min_gain >= 0:
            raise ValueError(f"StallStop: min_gain must be >= 0 (log-likelihood units), got {self.min_gain!r}")

    @property
    def rtol(self):
        return self.solver.rtol

    @property
    def atol(self):
        return self.solver.atol

    @property
    def norm(self):
        return self.solver.norm

    def init(self, fn, y, args, options, f_struct, aux_struct, tags):
        inner = self.solver.init(fn, y, args, options, f_struct, aux_struct, tags)
        return _StallState(inner, jnp.full(self.window + 1, jnp.inf), jnp.array(False))

    def step(self, fn, y, args, options, state, tags):
        y, inner, aux = self.solver.step(fn, y, args, options, state.inner, tags)
        leaves = jax.tree_util.tree_leaves(inner.f_info.residual)
        sse = sum(jnp.sum(r**2) for r in leaves)
        n = sum(jnp.count_nonzero(r) for r in leaves)  # zero-weight samples give exact zeros
        hist = jnp.roll(state.sse, -1).at[-1].set(sse)
        old = hist[0]  # inf until `window` steps have been taken
        gain = 0.5 * n * jnp.log(old / sse)
        stalled = jnp.isfinite(old) & (sse > 0) & (gain < self.min_gain)
        return y, _StallState(inner, hist, stalled), aux

    def terminate(self, fn, y, args, options, state, tags):
        done, result = self.solver.terminate(fn, y, args, options, state.inner, tags)
        return done | state.stalled, result

    def postprocess(self, fn, y, aux, args, options, state, tags, result):
        y, aux, stats = self.solver.postprocess(fn, y, aux, args, options, state.inner, tags, result)
        return y, aux, {**stats, "stalled": state.stalled}
