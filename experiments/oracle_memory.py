"""Issue 18: on the plant's TRUE hysteresis input, which part of the held-out miss is the operator set, which the memory.

Plain numpy + scipy, no smafl_jax import (records from tests/indep_plant.py).  For each failing matrix cell the output
is fitted by bounded linear least squares (operator weights >= 0, free linear/quadratic/cubic terms and offset, both
output signs, the better on training kept) on the first 70 % and scored on the last 30 % (RMSE / noise SD), with:
  - the plant's own operators (thresholds, tilts) and its own initial operator memory ("true_set_true_mem"),
  - the plant's own operators started by a rule: descended from / ascended to the trained extremes,
  - a dense 15 x 9 grid of thresholds (0..0.7 of the trained span) and tilts (0.3..3), started by the same rules,
    without and with a small ridge.
Each value is [train, held-out] over the noise SD.

    python experiments/oracle_memory.py        (about 5-10 min per cell on one core)
"""

import json
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import lsq_linear

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import indep_plant as ip


def plays(x, r, a, F0):
    F = np.array(F0, float).copy()
    out = np.empty((len(x), len(r)))
    for k, xk in enumerate(x):
        F = np.maximum(xk - r, np.minimum(a * (xk + r), F))
        out[k] = F
    return out


def fit_score(Phi, XC, y, h0, sd, ridge=0.0):
    """[train, held-out] RMSE / noise of the bounded least-squares fit on ``[Phi, XC]`` (first ``h0`` samples)."""
    n_ops = Phi.shape[1]
    best = None
    for s in (1, -1):
        A = np.hstack([s * Phi, XC])
        lb = np.r_[np.zeros(n_ops), -np.inf * np.ones(4)]
        sc = np.linalg.norm(A[:h0], axis=0) + 1e-12
        Ar = A[:h0] / sc
        if ridge:
            Ar = np.vstack([Ar, np.sqrt(ridge) * np.eye(A.shape[1])])
            b = np.r_[y[:h0], np.zeros(A.shape[1])]
        else:
            b = y[:h0]
        res = lsq_linear(Ar, b, bounds=(lb, np.inf * np.ones(A.shape[1])), method="bvls")
        yh = A @ (res.x / sc)
        tr = np.sqrt(np.mean((yh[:h0] - y[:h0]) ** 2)) / sd
        he = np.sqrt(np.mean((yh[h0:] - y[h0:]) ** 2)) / sd
        if best is None or tr < best[0]:
            best = (tr, he)
    return best


def fit_score_mask(Phi, XC, y, mask, h0, sd):
    """[train (masked samples), held-out] RMSE / noise of the bounded least-squares fit on the ``mask`` samples."""
    n_ops = Phi.shape[1]
    best = None
    for s in (1, -1):
        A = np.hstack([s * Phi, XC])
        lb = np.r_[np.zeros(n_ops), -np.inf * np.ones(4)]
        sc = np.linalg.norm(A[mask], axis=0) + 1e-12
        res = lsq_linear(A[mask] / sc, y[mask], bounds=(lb, np.inf * np.ones(A.shape[1])), method="bvls")
        yh = A @ (res.x / sc)
        tr = np.sqrt(np.mean((yh[mask] - y[mask]) ** 2)) / sd
        he = np.sqrt(np.mean((yh[h0:] - y[h0:]) ** 2)) / sd
        if best is None or tr < best[0]:
            best = (tr, he)
    return best


CELLS = {
    "pwm_cold": dict(drive="pwm", rate_hz=25, start="cold"),
    "stair_warm": dict(drive="staircase", rate_hz=10, start="warm"),
    "pwm_len": dict(drive="pwm", rate_hz=25, start="cold", orientation="length"),
    "steps_warm": dict(drive="steps", rate_hz=10, start="warm"),
    "ms_cold": dict(drive="multisine", rate_hz=25, start="cold"),
}
if __name__ != "__main__":
    todo = []
else:
    todo = [("pwm_cold", 7), ("stair_warm", 11), ("steps_warm", 13)]
for cell, seed in todo:
    r = ip.make_record(seed, minutes=10, **CELLS[cell])
    h0, sd, hy = r["heldout_start"], r["noise_sd"], r["truth"]["hysteresis"]
    x = ip._core(r["truth"], r["u"], r["dt"], upto="x")["x_h"]
    y = r["y"]
    XC = np.stack([x, x**2, x**3, np.ones_like(x)], 1)
    rt, at = np.array(hy["r"]), np.array(hy["alpha"])
    row = {"cell": cell, "seed": seed, "mem": hy["memory"]["kind"]}
    row["true_set_true_mem"] = fit_score(plays(x, rt, at, ip._initial_memory(hy, float(x[0]))), XC, y, h0, sd)
    for lab, F0 in (
        ("desc", np.maximum(x[0] - rt, np.minimum(at * (x[0] + rt), x[:h0].max() - rt))),
        ("asc", np.maximum(x[0] - rt, np.minimum(at * (x[0] + rt), x[:h0].min() + rt))),
    ):
        row[f"true_set_{lab}_mem"] = fit_score(plays(x, rt, at, F0), XC, y, h0, sd)
    # dense grid: r in [0, 0.7 x_span], alpha in 0.3..3 (log), memory: true-plant-independent rules
    xs = x[:h0].max()
    R, A = np.meshgrid(np.linspace(0.0, 0.7 * xs, 15), np.geomspace(0.3, 3.0, 9))
    R, A = R.ravel(), A.ravel()
    for lab, F0 in (
        ("desc", np.maximum(x[0] - R, np.minimum(A * (x[0] + R), x[:h0].max() - R))),
        ("asc", np.maximum(x[0] - R, np.minimum(A * (x[0] + R), x[:h0].min() + R))),
    ):
        P = plays(x, R, A, F0)
        for ridge in (0.0, 1e-4):
            row[f"dense_{lab}_ridge{ridge:g}"] = fit_score(P, XC, y, h0, sd, ridge)
    print(
        json.dumps({k: (tuple(round(v, 2) for v in val) if isinstance(val, tuple) else val) for k, val in row.items()}),
        flush=True,
    )
