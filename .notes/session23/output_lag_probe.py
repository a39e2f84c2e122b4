"""Would a first-order output lag close the training misfit of the saved G fits?  The saved model's prediction passed
through y_s[k] = a y_s[k-1] + (1-a) yhat[k-1] (plant B's sensor lag form), tau on a grid by training RMSE (first 70 %);
RMSE / noise on training and held-out, with the truth's lag for reference.  Post-hoc only: the fit itself never saw a lag."""
import json, sys
from pathlib import Path
import numpy as np
import smafl_jax as sj
sys.path[:0] = ["/work/main/experiments"]
import fit_plant_b as fb, indep_plant_b as pb

def lagged(y, a):
    out = np.empty_like(y); out[0] = y[0]
    for k in range(1, y.size):
        out[k] = a * out[k - 1] + (1 - a) * y[k - 1]
    return out

cells = {fb.name_of(c): c for c in fb.grid([6, 7], 10.0)}
for root, lin in (("/tmp/s23_lin", True), ("/tmp/cf_work", False)):
    for d in sorted(Path(root).glob("s[67]_*")):
        fj = d / "fit_G" / "fit.json"
        if not fj.exists() or d.name not in cells:
            continue
        c = cells[d.name]
        r = pb.make_record(c["seed"], **{k: v for k, v in c.items() if k != "seed"}, linear_thermal=lin)
        u, y, sd, h0, dt = r["voltage"], r["output"], r["noise_sd"], r["heldout_start"], 1 / c["rate_hz"]
        yh = np.asarray(sj.simulate(sj.load_model(fj), u, dt))
        e = lambda q, s: float(np.sqrt(np.mean((q[s] - y[s]) ** 2)) / sd)
        best = (e(yh, slice(0, h0)), 0.0, yh)
        for tau in [0.02, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4]:
            q = lagged(yh, np.exp(-dt / tau))
            if e(q, slice(0, h0)) < best[0]:
                best = (e(q, slice(0, h0)), tau, q)
        print(f"{d.name:36s} lin {lin!s:5s} true lag {r['truth']['sensor_lag_s']:.3f}  no lag {e(yh, slice(0, h0)):6.2f}/{e(yh, slice(h0, None)):6.2f}  best tau {best[1]:.2f}: {best[0]:6.2f}/{e(best[2], slice(h0, None)):6.2f}", flush=True)
