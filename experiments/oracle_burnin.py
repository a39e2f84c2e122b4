"""Issue 18: does fitting the gains only after the hysteresis input has visited both extremes of its training range
("burn-in mask") remove the initial-memory miss?  Plain numpy + scipy, no smafl_jax import.

After the time T* by which the input has reached both its training minimum and maximum, every play operator has
either touched one of its bounds (its state no longer depends on the initial memory) or cannot touch one inside the
training range (a constant, absorbed by the offset).  So samples after T* carry no memory ambiguity; a fit on them
alone should predict an in-range held-out part whatever the memory rule.  Values: [train, held-out] RMSE / noise SD.

    python experiments/oracle_burnin.py
"""

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import indep_plant as ip
from oracle_memory import CELLS, fit_score_mask, plays


def t_star(x, h0, tol):
    lo, hi = x[:h0].min(), x[:h0].max()
    span = hi - lo
    a = np.argmax(x[:h0] <= lo + tol * span)
    b = np.argmax(x[:h0] >= hi - tol * span)
    return int(max(a, b))


todo = [("pwm_cold", 7), ("stair_warm", 11), ("steps_warm", 13), ("stair_warm", 7), ("pwm_cold", 11), ("pwm_len", 7)]
for cell, seed in todo:
    r = ip.make_record(seed, minutes=10, **CELLS[cell])
    h0, sd, hy = r["heldout_start"], r["noise_sd"], r["truth"]["hysteresis"]
    x = ip._core(r["truth"], r["u"], r["dt"], upto="x")["x_h"]
    y = r["y"]
    XC = np.stack([x, x**2, x**3, np.ones_like(x)], 1)
    rt, at = np.array(hy["r"]), np.array(hy["alpha"])
    row = {"cell": cell, "seed": seed, "mem": hy["memory"]["kind"], "n_train": int(h0)}
    xs = x[:h0].max()
    R, A = np.meshgrid(np.linspace(0.0, 0.7 * xs, 15), np.geomspace(0.3, 3.0, 9))
    R, A = R.ravel(), A.ravel()
    Pt = plays(x, rt, at, np.maximum(x[0] - rt, np.minimum(at * (x[0] + rt), x[:h0].max() - rt)))
    Pd = plays(x, R, A, np.maximum(x[0] - R, np.minimum(A * (x[0] + R), x[:h0].max() - R)))
    for tol in (0.0, 0.02, 0.05):
        ts = t_star(x, h0, tol)
        row[f"tstar_frac_tol{tol}"] = round(ts / h0, 3)
        m = np.zeros(len(x), bool)
        m[ts:h0] = True
        row[f"true_set_desc_mask{tol}"] = fit_score_mask(Pt, XC, y, m, h0, sd)
        row[f"dense_desc_mask{tol}"] = fit_score_mask(Pd, XC, y, m, h0, sd)
    print(
        json.dumps({k: (tuple(round(v, 2) for v in val) if isinstance(val, tuple) else val) for k, val in row.items()}),
        flush=True,
    )
