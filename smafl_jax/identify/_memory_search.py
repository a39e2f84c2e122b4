"""Per-operator search of a fitted operator memory: where each operator sits between its bounds at t = 0.

Why: a fitted memory (`EUPI.with_fitted_memory`) starts every operator at one common position (descended, midway or
ascended: `smafl_jax.identify._choose.MEMORY_STARTS`), and the joint Levenberg-Marquardt refinement moves each position
only by its gradient, which is zero while an operator rests between its bounds.  On independent records whose plant
starts from a random operator memory, an EUPI with the plant's own thresholds and tilts stayed at 1.56x the noise on its
training samples from those starts and reached 1.01x from the plant's memory (session 29,
.notes/session29/oracle_grid.py).  An operator's start changes only its own design column, so the positions are
searched one operator at a time over a grid of fractions, the gains profiled by bounded least squares on the normal
equations (`linear.solve_gram`, one row and column updated per trial), for a few sweeps.
"""

from __future__ import annotations

from typing import Any

import jax.numpy as jnp
import numpy as np

from ..models._hysteresis import hysteresis_of
from .linear import solve_gram

__all__ = ["search_memory", "MEMORY_FRACTIONS", "MEMORY_SWEEPS"]

#: Start positions tried for each operator (0 = on its lower, ascending bound; 1 = on its upper, descending bound).
MEMORY_FRACTIONS = np.linspace(0.0, 1.0, 11)
#: Passes over the operators (the second catches operators whose best start moved with another's).
MEMORY_SWEEPS = 2


def search_memory(model: Any, data: tuple, weights: tuple, *, fractions=MEMORY_FRACTIONS, sweeps: int = MEMORY_SWEEPS):
    """``(model, loss)``: ``model`` (one record, fitted memory) with each operator's start position searched and the
    gains profiled (`init_linear`), ``loss = 0.5 x weighted SSE``; None when the model has no per-operator memory or
    its design does not expose the operator columns as the hysteresis computes them (e.g. an effect that filters them).

    ``data`` / ``weights``: one normalised ``(u, y, dt)`` record and its sample weights (0 = not fitted).  The current
    positions are candidates too; None as well when no operator moved.
    """
    from ._fit import _features, _linear_part, init_linear

    h = hysteresis_of(model)
    part = _linear_part(model)
    if h is None or part is None or len(data) != 1 or getattr(h, "memory", None) is None or getattr(h, "init", None) != "fitted":
        return None
    feats, nonneg, _ = part
    (u, y, dt), w = data[0], np.asarray(weights[0], dtype=np.float64)
    keep = w > 0
    sw = np.sqrt(w[keep])
    x = model.hysteresis_input(jnp.asarray(u), dt)
    current = 1.0 / (1.0 + np.exp(-np.asarray(h.memory, dtype=np.float64)))
    grid = np.asarray(fractions, dtype=np.float64)
    n = current.shape[0]
    rows = np.vstack([current[None, :], np.broadcast_to(grid[:, None], (grid.shape[0], n))])
    got = h.memory_columns(x, rows)
    if got is None:
        return None
    cols, C = got
    A = np.asarray(_features(feats, model, jnp.asarray(u), jnp.asarray(dt)), dtype=np.float64)  # the fit's jitted design
    C = np.asarray(C, dtype=np.float64)
    if not np.allclose(A[:, cols], C[0], rtol=1e-9, atol=1e-12 * max(float(np.max(np.abs(A))), 1.0)):
        return None  # the model's design is not the hysteresis' own operator columns
    A = A[keep] * sw[:, None]
    C = C[:, keep, :] * sw[None, :, None]
    b = np.asarray(y, dtype=np.float64)[keep] * sw
    G, hb, bb = A.T @ A, A.T @ b, float(b @ b)
    choice = np.zeros(n, dtype=int)  # row 0: the current positions
    best = solve_gram(G, hb, bb, nonneg).loss
    for _ in range(int(sweeps)):
        moved = False
        for i, j in enumerate(cols):
            X = C[:, :, i]  # (K, T): operator i's column for every start
            cross, cc, cb = X @ A, np.einsum("kt,kt->k", X, X), X @ b
            trial_best, k_best = best, choice[i]
            for k in range(X.shape[0]):
                if k == choice[i]:
                    continue
                Gk, hk = G.copy(), hb.copy()
                Gk[j, :] = cross[k]
                Gk[:, j] = cross[k]
                Gk[j, j] = cc[k]
                hk[j] = cb[k]
                loss = solve_gram(Gk, hk, bb, nonneg).loss
                if loss < trial_best * (1.0 - 1e-9):
                    trial_best, k_best = loss, k
            if k_best != choice[i]:
                choice[i], best, moved = k_best, trial_best, True
                A[:, j] = X[k_best]
                G[j, :] = cross[k_best]
                G[:, j] = cross[k_best]
                G[j, j] = cc[k_best]
                hb[j] = cb[k_best]
        if not moved:
            break
    if not np.any(choice):
        return None
    searched = model.with_hysteresis(h.with_memory_fractions(rows[choice, np.arange(n)]))
    # the gains by the fit's own solve (operators that never moved get gain 0, `linear.solve(drop_constant=True)`)
    searched = init_linear(searched, data, weights=weights)
    r = np.asarray(searched.simulate(jnp.asarray(u), dt)) - np.asarray(y)
    return searched, 0.5 * float(np.sum(w * r * r))
