"""Static classes on the plant's TRUE hysteresis input x_h (session 28): can the class reach the noise on training?

python .notes/session28/probe_truex.py SEED CELL(cold|warm) MINUTES CLASS [json fit opts]
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
x = np.asarray(r["sim"]["x_h"])
import smafl_jax as sj  # noqa: E402
from smafl_jax.report import fit_record  # noqa: E402

p = Path(f"/tmp/s28x_{seed}_{cell}_{minutes:g}.csv")
sj.atomic_write_csv(p, {"time_s": r["time"], "temperature_C": x, "displacement_mm": r["y"]})
rec = sj.load_record(p)
p70 = p.with_name(p.stem + "_70.csv")
sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "temperature_C": rec.u[:h0], "displacement_mm": rec.y[:h0]})
t0 = time.time()
model, doc, _ = fit_record(sj.load_record(p70), model=cls, **opts)
yhat = np.asarray(sj.simulate(model, rec.u, rec.dt))
e = yhat - rec.y
row = dict(seed=seed, cell=cell, minutes=minutes, cls=cls, opts=opts, input="true x_h",
           split_train=doc["metrics"]["train"]["rmse"] / sd, split_val=doc["metrics"]["validation"]["rmse"] / sd,
           train=float(np.sqrt(np.mean(e[:h0] ** 2)) / sd), held=float(np.sqrt(np.mean(e[h0:] ** 2)) / sd),
           seconds=time.time() - t0, model=doc["model"])  # fmt: skip
print(json.dumps({k: v for k, v in row.items() if k != "model"}))
with open("/tmp/s28_probe_truex.jsonl", "a") as f:
    f.write(json.dumps(row) + "\n")
