"""Train / held-out of one class on one independent plant-A record (session 28).

python .notes/session28/probe_class.py SEED CELL(cold|warm) MINUTES CLASS [json fit opts]
"""
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, "/work/main/tests")
import indep_plant as ip  # noqa: E402

seed, cell, minutes, cls = int(sys.argv[1]), sys.argv[2], float(sys.argv[3]), sys.argv[4]
opts = json.loads(sys.argv[5]) if len(sys.argv) > 5 else {}
kw = {"cold": dict(drive="random_levels", rate_hz=20, start="cold", orientation="length"),
      "warm": dict(drive="random_levels", rate_hz=10, start="warm")}[cell]  # fmt: skip
r = ip.make_record(seed, minutes=minutes, **kw)
h0, sd = r["heldout_start"], r["noise_sd"]
import os  # noqa: E402

import smafl_jax as sj  # noqa: E402
from smafl_jax.report import fit_record  # noqa: E402

R_MAX = float(os.environ.get("R_MAX", "0.5"))
if R_MAX != 0.5:  # experiment: symmetric/asymmetric thresholds up to R_MAX of the span (the grid rule stops at 0.5)
    import smafl_jax.models._eupi as _e  # private: experiment patches the grid rule

    _e.threshold_grid = lambda n: np.arange(1, int(n) + 1, dtype=np.float64) * (R_MAX / max(int(n), 1))
    opts = {**opts, "_r_max": R_MAX}

p = Path(f"/tmp/s28c_{seed}_{cell}_{minutes:g}.csv")
ip.write_csv(p, r)
rec = sj.load_record(p)
p70 = p.with_name(p.stem + "_70.csv")
sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
t0 = time.time()
model, doc, _ = fit_record(sj.load_record(p70), model=cls, **{k: v for k, v in opts.items() if not k.startswith("_")})
yhat = np.asarray(sj.simulate(model, rec.u, rec.dt))
e = yhat - rec.y
row = dict(seed=seed, cell=cell, minutes=minutes, cls=cls, opts=opts,
           split_train=doc["metrics"]["train"]["rmse"] / sd, split_val=doc["metrics"]["validation"]["rmse"] / sd,
           train=float(np.sqrt(np.mean(e[:h0] ** 2)) / sd), held=float(np.sqrt(np.mean(e[h0:] ** 2)) / sd),
           seconds=time.time() - t0, model=doc["model"])  # fmt: skip
print(json.dumps({k: v for k, v in row.items() if k != "model"}))
with open("/tmp/s28_probe_class.jsonl", "a") as f:
    f.write(json.dumps(row) + "\n")
