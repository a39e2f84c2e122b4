"""Why does the EUPI cascade hold out 162x / 85x on random_levels warm 10 Hz s22 / s25? (session 28)

python .notes/session28/probe_blowup.py SEED [cell] -> prints split figures, the held-out error over time, model params.
"""
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path("/work/main")
sys.path.insert(0, str(ROOT / "tests"))
import indep_plant as ip  # noqa: E402

seed = int(sys.argv[1])
kw = dict(drive="random_levels", rate_hz=10, start="warm")
if len(sys.argv) > 2 and sys.argv[2] == "cold":
    kw = dict(drive="random_levels", rate_hz=20, start="cold", orientation="length")
r = ip.make_record(seed, minutes=5.0, **kw)
h0, sd = r["heldout_start"], r["noise_sd"]
import smafl_jax as sj  # noqa: E402
from smafl_jax.report import fit_record  # noqa: E402

p = Path(f"/tmp/s28_{seed}_{kw['rate_hz']}.csv")
ip.write_csv(p, r)
rec = sj.load_record(p)
p70 = p.with_name(p.stem + "_70.csv")
sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
model, doc, _ = fit_record(sj.load_record(p70), model="cascade", thresholds=True, tilts=True)
yhat = np.asarray(sj.simulate(model, rec.u, rec.dt))
e = yhat - rec.y
print("train x", np.sqrt(np.mean(e[:h0] ** 2)) / sd, "held x", np.sqrt(np.mean(e[h0:] ** 2)) / sd)
print("u range train", rec.u[:h0].min(), rec.u[:h0].max(), "held", rec.u[h0:].min(), rec.u[h0:].max())
n = len(e)
for k in range(0, n, n // 30):
    print(f"t={rec.time[k]:7.1f} u={rec.u[k]:.2f} y={rec.y[k]:.4f} yhat={yhat[k]:.4f} e/sd={e[k] / sd:8.2f}")
print(model)
json.dump(doc, open(f"/tmp/s28_doc_{seed}.json", "w"), default=str, indent=1)
np.savez(f"/tmp/s28_{seed}.npz", u=rec.u, y=rec.y, yhat=yhat, h0=h0, sd=sd, xh=r.get("truth", {}).get("x_h", 0))
