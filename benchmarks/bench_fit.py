"""Identification speed: smafl_jax.fit vs scipy.optimize.least_squares on a numpy cascade.

Same model (Joule thermal lag + EUPI on the default grid, 29 trainable
parameters: k1 and the gains; k2 fixed, it does not enter the output), same
data (``datasets/steps.csv`` every 2nd sample, 1081 samples at 1 s; quick:
every 4th sample; the numpy loop + finite differences make the baseline take
minutes on the full bundled data), same start (the paper's k1 with the gains from the paper's
bounded least squares at that k1), measured in one process:

* baseline: ``scipy.optimize.least_squares`` (trf, default 2-point
  finite-difference Jacobian, default tolerances, bounds k1 > 0, play gains
  >= 0) on a plain numpy loop of the cascade;
* ours, default ``smafl_jax.fit(start, ...)``: k1 profile over 33 candidates
  (incl. the start's k1) by vmap + BVLS, Brent on log k1, then joint LM,
  warm and cold (with JIT compilation);
* ours, LM only from the same start (``init=None``): the plain joint
  gradient method, shown for honesty: on this ill-conditioned problem it does
  not reach scipy's loss within 300 steps (see its note).

The final losses are reported with each row: "same final loss" is checked,
not assumed.  Ratio = baseline seconds / ours seconds (> 1: ours faster).

    python -m benchmarks.bench_fit [--quick]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

try:
    from ._common import progress, row
except ImportError:  # run as a script
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from benchmarks._common import progress, row

ROOT = Path(__file__).resolve().parents[1]
RATIO_MEANING = "baseline seconds / ours seconds (> 1: ours faster)"


def numpy_cascade(p, u, dt, fixed):
    """Plain numpy loop of the cascade: p = [k1, gain, v..., w..., poly..., offset]."""
    k1, k2 = p[0], fixed["k2"]
    theta_w = p[1:]
    a, g = np.exp(-k1 * dt), k2 / k1
    theta = g * u[0] ** 2
    r, al = fixed["r"], fixed["alpha"]
    s_prev = None
    y = np.empty(u.shape[0])
    npoly = fixed["npoly"]
    for k in range(u.shape[0]):
        theta = a * theta + (1 - a) * g * u[k] ** 2
        ueff = np.sqrt(max(theta, 0.0) * k1 / k2)
        s = (ueff - fixed["u_ref"]) / fixed["u_span"]
        if s_prev is None:
            F = al * (s + r)  # "descended" initial state
        F = np.maximum(s - r, np.minimum(al * (s + r), F))
        s_prev = s
        feats = np.concatenate(([s], F, [s ** (m + 2) for m in range(npoly)], [1.0]))
        y[k] = feats @ theta_w
    return y


def _problem(quick):
    import jax.numpy as jnp

    import smafl_jax as sj

    r = sj.load_record(ROOT / "datasets" / "steps.csv")
    step = 4 if quick else 2
    recs = [(r.u[::step], r.y[::step], step * r.dt)]
    start = sj.init_linear(sj.Cascade.from_range(7.4), recs)
    e = start.hysteresis
    n_alpha, n_ra = e.w.shape
    fixed = {
        "k2": float(start.thermal.k2),
        "r": np.concatenate([np.asarray(e.r_sym), np.tile(np.asarray(e.r_asym), n_alpha)]),
        "alpha": np.concatenate([np.ones(e.r_sym.shape[0]), np.repeat(np.asarray(e.alpha), n_ra)]),
        "u_ref": float(e.u_ref),
        "u_span": float(e.u_span),
        "npoly": int(e.poly.shape[0]),
    }
    p0 = np.concatenate([[float(start.thermal.k1)], np.asarray(e.linear_weights())])
    nonneg = np.concatenate([[True], e.nonnegative_columns()])
    del jnp
    return recs, start, fixed, p0, nonneg


def _scipy_fit(recs, fixed, p0, nonneg):
    from scipy.optimize import least_squares

    def res(p):
        return np.concatenate([numpy_cascade(p, u, dt, fixed) - y for u, y, dt in recs])

    lb = np.where(nonneg, 0.0, -np.inf)
    lb[0] = 1e-6
    t0 = time.perf_counter()
    sol = least_squares(res, np.clip(p0, lb + 1e-12 * (lb > -np.inf), None), bounds=(lb, np.inf))
    return time.perf_counter() - t0, float(sol.cost), float(sol.x[0]), int(sol.nfev)


def run(quick: bool = False) -> list[dict]:
    import smafl_jax as sj

    recs, start, fixed, p0, nonneg = _problem(quick)
    n = sum(u.shape[0] for u, _, _ in recs)
    # numpy model check against ours before timing anything
    y_np = numpy_cascade(p0, recs[0][0], recs[0][2], fixed)
    y_j = np.asarray(sj.simulate(start, recs[0][0], recs[0][2]))
    if not np.allclose(y_np, y_j, atol=1e-9):
        raise RuntimeError(f"numpy cascade disagrees with smafl_jax (max diff {np.max(np.abs(y_np - y_j)):.3g})")

    def ours(init):
        t0 = time.perf_counter()
        r = sj.fit(start, recs, init=init, solver="lm")
        return time.perf_counter() - t0, r

    progress(f"fit: ours, default pipeline, cold then warm ({n} samples)")
    cold_s, r_cold = ours("auto")
    full_s, r_full = ours("auto")
    progress("fit: ours, LM only from the same start (warm)")
    ours(None)
    warm_s, r_warm = ours(None)
    progress("fit: scipy least_squares on the numpy cascade (2-point FD Jacobian); this is the slow one")
    sp_s, sp_loss, sp_k1, sp_nfev = _scipy_fit(recs, fixed, p0, nonneg)
    size = {"n_samples": n, "n_params": int(p0.size), "quick": quick}

    def note(r):
        same = r.loss <= sp_loss * (1 + 1e-6)
        return (
            f"final loss ours {r.loss:.6g} (k1 {float(r.model.thermal.k1):.5g}, {r.n_steps} steps, {r.message}) vs scipy {sp_loss:.6g} "
            f"(k1 {sp_k1:.5g}, {sp_nfev} residual evals + FD Jacobians); ours reached scipy's loss: {'yes' if same else 'NO'}"
        )

    return [
        row(
            "fit (profile k1 + LM), warm vs scipy trf + FD",
            full_s,
            sp_s,
            "s",
            ratio=sp_s / full_s,
            note=note(r_full),
            ours_loss=r_full.loss,
            baseline_loss=sp_loss,
            **size,
        ),
        row(
            "fit (profile k1 + LM) incl. JIT compile vs scipy",
            cold_s,
            sp_s,
            "s",
            ratio=sp_s / cold_s,
            note=note(r_cold),
            ours_loss=r_cold.loss,
            baseline_loss=sp_loss,
            **size,
        ),
        row(
            "LM only from the same start (warm) vs scipy",
            warm_s,
            sp_s,
            "s",
            ratio=sp_s / warm_s,
            note=note(r_warm),
            ours_loss=r_warm.loss,
            baseline_loss=sp_loss,
            **size,
        ),
    ]


if __name__ == "__main__":
    import json

    rows = run(quick="--quick" in sys.argv)
    for r in rows:
        print(json.dumps(r))
