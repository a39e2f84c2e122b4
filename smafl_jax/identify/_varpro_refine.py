"""Joint refinement by variable projection: Levenberg-Marquardt over the nonlinear parameters, the gains profiled.

Why: the joint refinement (`smafl_jax.identify.fit`, solver ``"lm"``) trains the operator gains together with the
thresholds, tilts, thermal rate, thermal start and operator memory.  Dozens of nearly collinear operator columns make
that problem badly conditioned: on an independent cold-start step record (plant C r03: 3 true operators, 5 Hz, SNR
3300) joint LM on the default 24-operator grid stopped at 10.6x the noise on its own training samples, and 3000 steps
without the stall rule reached 3.45x; the true plant refined from itself stays at 1.07x.  With the gains solved
exactly at every point (variable projection, Golub-Pereyra) the same start reached 3.37x in 179 steps, and 1.02x after
a search of the operator memory and a second search (session 44, .notes/session44/verify_r03.py).

At every evaluation the bounded least-squares problem of the gains is solved on the host (`linear.solve_gram`) for
its active set (the operator columns it keeps above 0, and every signed column); that set carries no gradient (it is
piecewise constant), and the gains of the set come from column-scaled normal equations, differentiated through.  So the
residual is ``A(x) theta(x) - b`` with ``theta(x)`` the exact bounded solution.  A round is one LM search (with the
joint LM's stall rule); another round restarts LM (fresh damping) while the bounded loss still falls.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ..models._constraints import constrain, unconstrain
from ..models._hysteresis import hysteresis_of, record_model
from ._stall import StallStop
from .linear import solve_gram

__all__ = ["VARPRO_ROUNDS", "nonlinear_spec", "refine_projected"]

#: LM searches of `refine_projected` at most, each restarted from the last (measured on plant C r03: the second gained
#: nothing; a restart helps where LM stopped at a kink of the active set).
VARPRO_ROUNDS = 4
#: Diagonal jitter of the projected normal equations, relative to their mean diagonal (unit-scaled columns).
_JITTER = 1e-10


def nonlinear_spec(model, spec):
    """``spec`` with the hysteresis' linear gains (`linear_fields`) switched off: what the projection searches."""
    h = hysteresis_of(model)
    fields = [f for f in h.linear_fields() if eqx.is_array(getattr(h, f))]
    return eqx.tree_at(lambda s: [getattr(s.hysteresis, f) for f in fields], spec, [False] * len(fields))


def _design(feats, model, args):
    """Weighted design matrix and target of every record, stacked (zero-weight rows stay, as zeros)."""
    A = jnp.concatenate([jnp.sqrt(w)[:, None] * feats(record_model(model, i), u, d) for i, (u, y, d, w) in enumerate(args)])
    b = jnp.concatenate([jnp.sqrt(w) * y for (_, y, _, w) in args])
    return A, b


def _nnls_active(G, h, nonneg):
    """Host side: the columns the bounded least-squares solution of the normal equations keeps (signed ones always)."""
    x = solve_gram(np.asarray(G), np.asarray(h), 0.0, np.asarray(nonneg)).x
    return np.asarray((~np.asarray(nonneg)) | (x > 0), dtype=np.float64)


def _projected_residual(feats, model, args, nonneg):
    A, b = _design(feats, model, args)
    # column scaling conditions the normal equations; it does not change the projection, so it carries no gradient
    scale = jax.lax.stop_gradient(jnp.sqrt(jnp.sum(A * A, axis=0)) + 1e-300)
    As = A / scale[None, :]
    G, h = As.T @ As, As.T @ b
    # the active set of the exact bounded solution at this point (no gradient: piecewise constant), then the gains of
    # that set by the normal equations, differentiable; inactive columns get gain 0
    spec = jax.ShapeDtypeStruct((G.shape[0],), G.dtype)
    active = jax.pure_callback(_nnls_active, spec, jax.lax.stop_gradient(G), jax.lax.stop_gradient(h), nonneg)
    mask = active[:, None] * active[None, :]
    G = G * mask + jnp.diag(1.0 - active)
    G = G + _JITTER * jnp.trace(G) / G.shape[0] * jnp.eye(G.shape[0], dtype=G.dtype)
    c = jnp.linalg.solve(G, h * active)
    return As @ c - b


def _lm_round_impl(feats, raw, static, args, nonneg, max_steps, rtol, atol, stall):
    def fn(p, _):
        return _projected_residual(feats, constrain(eqx.combine(p, static)), args, nonneg)

    solver = optx.LevenbergMarquardt(rtol=rtol, atol=atol)
    solver = StallStop(solver) if stall else solver
    sol = optx.least_squares(fn, solver, raw, None, max_steps=max_steps, throw=False)
    return sol.value, sol.stats["num_steps"], sol.result == optx.RESULTS.successful


# One trace per (design function, model structure, record shapes, options); the counter lets a test check that new
# parameter values never retrace.
_lm_round_traced = eqx.debug.assert_max_traces(_lm_round_impl, max_traces=None)
_lm_round = eqx.filter_jit(_lm_round_traced)


def refine_projected(model, spec, args, bvls, feats, *, max_steps, rtol, atol, stall=True, rounds=VARPRO_ROUNDS):
    """``(model, loss, n_steps, converged)`` after up to ``rounds`` projected LM searches from ``model``.

    ``args``: the fit's ``(u, y, dt, w)`` per record; ``bvls(model) -> (model with its BVLS gains, loss, gains)``;
    ``feats``: the design function of `smafl_jax.identify._fit._linear_part`; ``max_steps`` bounds each round;
    ``stall``: each round also stops once its steps stop paying (`StallStop`), as the joint LM does.
    """
    spec_nl = nonlinear_spec(model, spec)
    model, loss, gains = bvls(model)
    if gains is None:
        return model, loss, 0, False  # the model is not finite here: the caller keeps its start
    if not jax.tree_util.tree_leaves(eqx.filter(spec_nl, lambda s: s is True)):
        return model, loss, 0, True  # nothing nonlinear to train: the BVLS gains are the fit
    nonneg = np.asarray(hysteresis_of(model).nonnegative_columns())
    n_steps, ok = 0, True
    for _ in range(int(rounds)):
        raw, static = eqx.partition(unconstrain(model), spec_nl)
        value, n, good = _lm_round(feats, raw, static, args, jnp.asarray(nonneg), max_steps, rtol, atol, bool(stall))
        n_steps += int(n)
        moved = constrain(eqx.combine(value, static))
        if not all(bool(jnp.all(jnp.isfinite(leaf))) for leaf in jax.tree_util.tree_leaves(eqx.filter(moved, eqx.is_array))):
            break
        got = bvls(moved)
        if not np.isfinite(got[1]) or not got[1] < loss * (1.0 - 1e-9):
            break
        model, loss, _ = got
        ok = bool(good)
    return model, loss, n_steps, ok
