"""A weakly informative prior on the hysteresis gains: one operator should not move the output by far more than the
output's whole observed range.

Why: an operator whose output barely moves over a record (its threshold above most of the input, or a column that
sits near a constant level) is almost collinear with the output offset.  The unpenalised least squares then buys a
last bit of training error with huge cancelling gains (measured on the shared cavatappi record s1_t2: operator gains
9 344 and 17 302 against an offset of 30 189 on a 45 mm output).  The cancellation holds only for the operator
states of that record; a new run that starts elsewhere, or leaves the trained range, sees the gains without the
offset that cancelled them (that model's median RMSE on the other three runs: 397 mm).

The prior: each gain ``x_j`` of a non-negative (operator) column, in the model's own normalised input units (one
operator that sweeps the whole input range moves the output by ``x_j``), is ``N(0, (kappa * range(y))^2)``; the noise
variance is the residual variance of the unpenalised solve (the plug-in estimate).  The gains are then the MAP at the
model's nonlinear parameters:

    min 0.5 |A x - b|^2 + 0.5 sum_j (sigma^2 / (kappa range(y))^2) x_j^2,   x_j >= 0 on operator columns

A proper prior (its weight does not grow with the number of samples): gains of a few times the output range cost a
few sigma^2 in total and are kept whenever the data ask for them; only gains hundreds of times the range, which the
data barely support, are pulled in.  The offset and the polynomial terms are not penalised.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._choices import GAIN_PRIOR
from .._errors import UserInputError
from .linear import solve
from .varpro import FIT_SOLVE

__all__ = ["GAIN_PRIOR", "check_gain_prior", "map_gains"]


def check_gain_prior(kappa: Any) -> float | None:
    """``kappa`` as a float > 0, or None (no prior); a `UserInputError` otherwise."""
    if kappa is None:
        return None
    try:
        k = float(kappa)
    except (TypeError, ValueError):
        raise UserInputError(f"gain_prior must be a number > 0 or None, got {kappa!r}") from None
    if not (np.isfinite(k) and k > 0.0):
        raise UserInputError(f"gain_prior must be a finite number > 0 or None, got {kappa!r}")
    return k


def map_gains(A: np.ndarray, b: np.ndarray, nonneg: np.ndarray, kappa: float) -> tuple[np.ndarray, dict[str, Any]]:
    """The MAP gains under the prior (module docstring) for the design ``A`` (weighted rows) and target ``b``.

    Returns ``(x, info)``; ``info``: ``kappa``, ``sigma`` (the plug-in noise SD), ``output_range``, the largest operator
    gain without and with the prior, and the training RMSE without and with it (``rmse_free``, ``rmse``).
    """
    nonneg = np.asarray(nonneg, bool)
    n = max(len(b), 1)
    free = solve(A, b, nonneg, **FIT_SOLVE)
    spread = float(np.ptp(b)) if len(b) else 0.0
    sig2 = 2.0 * free.loss / n
    info = {
        "kappa": kappa,
        "sigma": float(np.sqrt(sig2)),
        "output_range": spread,
        "largest_gain_free": float(np.max(free.x[nonneg], initial=0.0)),
    }
    if spread <= 0.0 or sig2 <= 0.0 or not np.any(nonneg):  # nothing to scale the prior by, or an exact fit
        x = free.x
    else:
        penalty = np.diag(np.where(nonneg, sig2 / (kappa * spread) ** 2, 0.0))
        x = solve(A, b, nonneg, penalty=penalty, **FIT_SOLVE).x
    r = A @ x - b
    info.update(
        largest_gain=float(np.max(x[nonneg], initial=0.0)),
        rmse_free=float(np.sqrt(sig2)),
        rmse=float(np.sqrt(float(r @ r) / n)),
    )
    return x, info
