"""Residual diagnostics: whiteness, Ljung-Box, cross-correlation, candidate-signal correlations.

All statistics are plain numpy/scipy on the residual ``e = y - yhat``.  The
confidence bounds are the usual large-sample ones (``+-1.96 / sqrt(n)`` for a
white residual).  Correlations with candidate signals are judged on an
*effective* sample size (Bartlett's formula with both autocorrelations), since
residuals of a simulation model are strongly autocorrelated and the naive
``n`` would make every correlation look significant.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

__all__ = [
    "autocorrelation",
    "ljung_box",
    "cross_correlation",
    "effective_n",
    "candidate_signals",
    "signal_correlations",
    "whiteness_report",
]


def _center(x):
    x = np.asarray(x, dtype=np.float64)
    return x - x.mean()


def autocorrelation(e, max_lag):
    """Sample autocorrelation ``rho(0..max_lag)`` (biased estimator, ``rho(0) = 1``)."""
    e = _center(e)
    n = e.size
    max_lag = int(min(max_lag, n - 1))
    var = float(e @ e)
    if var == 0:
        return np.r_[1.0, np.zeros(max_lag)]
    return np.array([float(e[: n - k] @ e[k:]) / var for k in range(max_lag + 1)])


def ljung_box(e, lags):
    """Ljung-Box statistic and p-value for ``lags`` autocorrelations (H0: white)."""
    e = np.asarray(e, dtype=np.float64)
    n = e.size
    lags = int(min(lags, n - 2))
    rho = autocorrelation(e, lags)[1:]
    q = float(n * (n + 2) * np.sum(rho**2 / (n - np.arange(1, lags + 1))))
    return {"Q": q, "lags": lags, "p_value": float(stats.chi2.sf(q, lags))}


def cross_correlation(e, x, max_lag):
    """``corr(e(k), x(k - lag))`` for lag = 0..max_lag (the input and its past)."""
    e, x = _center(e), _center(x)
    n = e.size
    den = np.sqrt(float(e @ e) * float(x @ x))
    if den == 0:
        return np.zeros(int(max_lag) + 1)
    return np.array([float(e[lag:] @ x[: n - lag]) / den for lag in range(int(max_lag) + 1)])


def effective_n(a, b, max_lag=200):
    """Bartlett effective sample size for the correlation of two autocorrelated series."""
    n = np.size(a)
    L = int(min(max_lag, n // 4))
    ra, rb = autocorrelation(a, L), autocorrelation(b, L)
    s = 1.0 + 2.0 * float(np.sum(ra[1:] * rb[1:]))
    return float(np.clip(n / max(s, 1.0), 3.0, n))


def _rate(x, dt):
    return np.gradient(np.asarray(x, float), dt)


def candidate_signals(time, u, yhat, dt, *, x=None, extra=None):
    """Signals the residual may depend on: rates, thermal state, direction, level, time, cycles, extra columns."""
    u = np.asarray(u, float)
    yhat = np.asarray(yhat, float)
    sig = {
        "input": u,
        "input_rate": _rate(u, dt),
        "abs_input_rate": np.abs(_rate(u, dt)),
        "output_level": yhat,
        "output_level_sq": _center(yhat) ** 2,
        "output_rate": _rate(yhat, dt),
        "direction": np.sign(_rate(yhat, dt)),
        "elapsed_time": np.asarray(time, float) - float(time[0]),
    }
    if x is not None:
        sig["thermal_state"] = np.asarray(x, float) ** 2
        sig["thermal_rate"] = _rate(sig["thermal_state"], dt)
        sig["heating_cooling"] = np.sign(sig["thermal_rate"])
    # cycle count: number of completed rises through the input mid-level
    mid = 0.5 * (u.min() + u.max())
    up = np.r_[0, (u[1:] >= mid) & (u[:-1] < mid)]
    sig["cycle_count"] = np.cumsum(up).astype(float)
    for k, v in (extra or {}).items():
        v = np.asarray(v, float)
        if v.shape == u.shape and np.all(np.isfinite(v)) and np.ptp(v) > 0:
            sig[f"extra:{k}"] = v
    return sig


def signal_correlations(e, signals):
    """Correlation of ``e`` with each signal, with Bartlett-effective n and a two-sided p-value."""
    out = {}
    e = np.asarray(e, float)
    for name, s in signals.items():
        s = np.asarray(s, float)
        if s.shape != e.shape or np.ptp(s) == 0 or np.ptp(e) == 0:
            continue
        r = float(np.corrcoef(e, s)[0, 1])
        n_eff = effective_n(e, s)
        z = np.arctanh(np.clip(r, -0.999999, 0.999999)) * np.sqrt(max(n_eff - 3.0, 1.0))
        out[name] = {"corr": r, "n_eff": n_eff, "p_value": float(2 * stats.norm.sf(abs(z)))}
    return out


def whiteness_report(e, u, *, max_lag=50):
    """Autocorrelation with bounds, Ljung-Box, and cross-correlation with the input's past."""
    e = np.asarray(e, float)
    n = e.size
    max_lag = int(min(max_lag, n // 3))
    rho = autocorrelation(e, max_lag)
    bound = 1.96 / np.sqrt(n)
    ccf = cross_correlation(e, u, max_lag)
    return {
        "n": int(n),
        "acf": rho.tolist(),
        "acf_bound": float(bound),
        "acf_fraction_outside": float(np.mean(np.abs(rho[1:]) > bound)) if max_lag else 0.0,
        "ljung_box": ljung_box(e, min(20, max_lag)) if max_lag >= 1 else None,
        "ccf_input": ccf.tolist(),
        "ccf_fraction_outside": float(np.mean(np.abs(ccf) > bound)),
        "ccf_max_abs": float(np.max(np.abs(ccf))),
        "ccf_argmax_lag": int(np.argmax(np.abs(ccf))),
        "white": bool(ljung_box(e, min(20, max_lag))["p_value"] > 0.01) if max_lag >= 1 else None,
    }
