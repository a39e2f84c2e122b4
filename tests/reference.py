"""Plain numpy loops used as the reference for every recurrence in the tests."""

import numpy as np


def play_loop(u, r, alpha, y0):
    r = np.atleast_1d(np.asarray(r, float))
    alpha = np.broadcast_to(np.asarray(alpha, float), r.shape)
    y = np.array(np.broadcast_to(y0, r.shape), dtype=float)
    out = np.empty((len(u), len(r)))
    for k, uk in enumerate(u):
        for i in range(len(r)):
            y[i] = max(uk - r[i], min(alpha[i] * (uk + r[i]), y[i]))
        out[k] = y
    return out


def eupi_loop(m, u):
    """EUPI output written term by term from eq. (2), on numpy arrays."""
    u = np.asarray(u, float)
    s = (u - float(m.u_ref)) / float(m.u_span)
    r_sym, r_asym, alpha = (np.asarray(x, float) for x in (m.r_sym, m.r_asym, m.alpha))
    Fs = play_loop(s, r_sym, 1.0, s[0] + r_sym if m.init == "descended" else 0.0)
    out = float(m.gain) * s + Fs @ np.asarray(m.v, float)
    w = np.asarray(m.w, float)
    for i, a in enumerate(alpha):
        y0a = a * (s[0] + r_asym) if m.init == "descended" else 0.0
        Fa = play_loop(s, r_asym, a, y0a)
        out = out + Fa @ w[i]
    for j, c in enumerate(np.asarray(m.poly, float)):
        n = j + 2  # s^n on the model's range [0, 1], continued with value and slope outside it
        out = out + c * np.array([sk**n if 0.0 <= sk <= 1.0 else (1.0 + n * (sk - 1.0) if sk > 1.0 else 0.0) for sk in s])
    return out + float(m.offset)


def lag_loop(x, dt, tau):
    """Exact first-order lag of a zero-order-hold signal, at rest with the first sample."""
    a = np.exp(-dt / tau)
    out = np.empty_like(np.asarray(x, float))
    z = x[0]
    for k, xk in enumerate(x):
        z = a * z + (1.0 - a) * xk
        out[k] = z
    return out


def thermal_loop(u, dt, k1, k2, theta0):
    a = np.exp(-k1 * dt)
    g = k2 / k1
    theta = theta0
    out = np.empty(len(u))
    for k, uk in enumerate(u):
        theta = a * theta + (1 - a) * g * uk * uk
        out[k] = theta
    return out


def random_reversals(rng, n, lo=0.0, hi=7.4, n_knots=12):
    """Piecewise-linear input with random reversal points, plus small jitter."""
    knots = rng.uniform(lo, hi, n_knots)
    t = np.linspace(0, 1, n)
    u = np.interp(t, np.linspace(0, 1, n_knots), knots)
    return np.clip(u + 0.05 * rng.standard_normal(n), lo, hi)
