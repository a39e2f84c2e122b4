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

Columns that barely move get no gain at all (`WEAK_RTOL`): an operator whose output moves by less than 0.1 % of the
largest column over the training samples is collinear with the offset there, and a prior whose weight does not grow
with the record lets a tiny, consistent trend over thousands of samples buy it a huge gain.  Measured on plant C r10
(experiments/indep_plant_c.py, the EUPI cascade fitted on 6 300 samples): an operator whose column moved by 6e-5 of the
input span carried a gain near 50 (19.557-19.560 mm of a 3.4 mm stroke, cancelled by the offset); a new run of the same
plant moved it by 5.7 mm and scored 200x / 434x the noise.  With such columns at gain 0: training RMSE 1.160 -> 1.176x
the noise, the new runs 5.0x / 6.3x.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._choices import GAIN_PRIOR
from .._errors import UserInputError
from .linear import solve
from .varpro import FIT_SOLVE

__all__ = ["GAIN_PRIOR", "WEAK_RTOL", "check_gain_prior", "map_gains"]

#: An operator column whose peak-to-peak over the training rows is at most this fraction of the largest |entry| of the
#: design gets gain 0 in the MAP solve (module docstring); `linear.DEAD_RTOL` (columns that never moved) is far smaller.
WEAK_RTOL = 1e-3


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
    gain without and with the prior, the training RMSE without and with it (``rmse_free``, ``rmse``), and
    ``weak_columns``, the operator columns set to 0 because they barely move (`WEAK_RTOL`).
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
        x = solve(A, b, nonneg, penalty=penalty, **{**FIT_SOLVE, "dead_rtol": WEAK_RTOL}).x
    r = A @ x - b
    moves = np.ptp(A, axis=0) if len(b) else np.zeros(A.shape[1])
    weak = nonneg & (moves <= WEAK_RTOL * max(float(np.max(np.abs(A), initial=0.0)), 1e-300)) & (moves > 0.0)
    info.update(
        weak_columns=int(np.sum(weak & (x == 0.0))),
        largest_gain=float(np.max(x[nonneg], initial=0.0)),
        rmse_free=float(np.sqrt(sig2)),
        rmse=float(np.sqrt(float(r @ r) / n)),
    )
    return x, info
