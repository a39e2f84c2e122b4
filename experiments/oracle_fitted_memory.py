"""Issue 18: is the held-out miss an optimisation problem (memory not found) or an identifiability one?

Plain numpy + scipy, no smafl_jax import.  On the plant's TRUE hysteresis input, each play operator's output is
``clip(z0, L_t, U_t)`` (a composition of clips is a clip), so the output is linear in the gains and piecewise
linear in each operator's initial state ``z0``.  Fit: alternate bounded least squares for the gains and a 1-D grid
search of each operator's ``z0`` over its admissible interval at the first input (coordinate descent), from the
descended and the ascended rule; the lower training loss wins.  Done for the plant's own operators and for a dense
15 x 9 grid.  Values: [train, held-out] RMSE / noise SD.

    python experiments/oracle_fitted_memory.py
"""

import json
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import lsq_linear

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import indep_plant as ip
from oracle_memory import CELLS


def clip_bounds(x, r, a):
    """(L, U) of shape (T, n): operator output = clip(z0, L_t, U_t)."""
    L = np.full(len(r), -np.inf)
    U = np.full(len(r), np.inf)
    Ls, Us = np.empty((len(x), len(r))), np.empty((len(x), len(r)))
    for k, xk in enumerate(x):
        lo, up = xk - r, np.maximum(xk - r, a * (xk + r))
        L, U = np.clip(L, lo, up), np.clip(U, lo, up)
        Ls[k], Us[k] = L, U
    return Ls, Us


def gains(Phi, XC, y, h0, sign):
    A = np.hstack([sign * Phi, XC])
    lb = np.r_[np.zeros(Phi.shape[1]), -np.inf * np.ones(XC.shape[1])]
    sc = np.linalg.norm(A[:h0], axis=0) + 1e-12
    res = lsq_linear(A[:h0] / sc, y[:h0], bounds=(lb, np.inf * np.ones(A.shape[1])), method="bvls")
    return res.x / sc


def fit(x, y, r, a, XC, h0, sd, sweeps=6, n_cand=25):
    L, U = clip_bounds(x, r, a)
    lo0, up0 = x[0] - r, np.maximum(x[0] - r, a * (x[0] + r))
    best = None
    for sign in (1, -1):
        for lab, z0 in (("desc", up0.copy()), ("asc", lo0.copy())):
            for sweep in range(sweeps + 1):
                Phi = np.clip(z0, L, U)
                th = gains(Phi, XC, y, h0, sign)
                if sweep == sweeps:
                    break
                w = sign * th[: len(r)]
                pred = np.hstack([sign * Phi, XC]) @ th
                for i in np.argsort(-np.abs(w)):
                    if w[i] == 0.0:
                        continue
                    base = pred[:h0] - w[i] * Phi[:h0, i]
                    cand = np.r_[np.linspace(lo0[i], up0[i], n_cand), z0[i]]
                    cols = np.clip(cand[None, :], L[:h0, i : i + 1], U[:h0, i : i + 1])  # (h0, n_cand)
                    sse = ((base[:, None] + w[i] * cols - y[:h0, None]) ** 2).sum(0)
                    j = int(np.argmin(sse))
                    z0[i] = cand[j]
                    Phi[:, i] = np.clip(z0[i], L[:, i], U[:, i])
                    pred = np.hstack([sign * Phi, XC]) @ th
            yh = np.hstack([sign * Phi, XC]) @ th
            tr = np.sqrt(np.mean((yh[:h0] - y[:h0]) ** 2)) / sd
            he = np.sqrt(np.mean((yh[h0:] - y[h0:]) ** 2)) / sd
            if best is None or tr < best[0]:
                best = (round(tr, 2), round(he, 2), sign, lab)
    return best


todo = [("pwm_cold", 7), ("stair_warm", 11), ("steps_warm", 13), ("pwm_cold", 11)]
for cell, seed in todo:
    r = ip.make_record(seed, minutes=10, **CELLS[cell])
    h0, sd, hy = r["heldout_start"], r["noise_sd"], r["truth"]["hysteresis"]
    x = ip._core(r["truth"], r["u"], r["dt"], upto="x")["x_h"]
    y = r["y"]
    XC = np.stack([x, x**2, x**3, np.ones_like(x)], 1)
    rt, at = np.array(hy["r"]), np.array(hy["alpha"])
    row = {"cell": cell, "seed": seed, "mem": hy["memory"]["kind"], "n_ops": len(rt)}
    row["true_set_fitted_mem"] = fit(x, y, rt, at, XC, h0, sd)
    xs = x[:h0].max()
    R, A = np.meshgrid(np.linspace(0.0, 0.7 * xs, 15), np.geomspace(0.3, 3.0, 9))
    row["dense_fitted_mem"] = fit(x, y, R.ravel(), A.ravel(), XC, h0, sd)
    print(json.dumps(row), flush=True)
