"""Fit one random-cell record with the defaults and save the prediction (session 48 probe).

python .notes/session48/probe_record.py ROOT SEED OUT.npz [fit_record options as JSON]
"""

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

root, seed, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
opts = json.loads(sys.argv[4]) if len(sys.argv) > 4 else {}
here = Path(__file__).resolve()
line = subprocess.check_output([sys.executable, str(here.parent / "random_cells.py"), str(seed)], text=True).strip()
minutes, cell = float(line.split("\t")[1]), json.loads(line.split("\t")[2])
kw = next(iter(cell.values()))
sys.path.insert(0, str(here.parents[2] / "tests"))
sys.path.insert(0, str(Path(root).resolve()))
import indep_plant as ip  # noqa: E402

import smafl_jax as sj  # noqa: E402
from smafl_jax.report import fit_record  # noqa: E402

r = ip.make_record(seed, minutes=minutes, **kw)
h0 = r["heldout_start"]
p = f"/tmp/s48/rec_{seed}.csv"
ip.write_csv(p, r)
rec = sj.load_record(p)
p70 = f"/tmp/s48/rec70_{seed}.csv"
sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
t0 = time.time()
model, doc, _ = fit_record(sj.load_record(p70), **opts)
yh = np.asarray(sj.simulate(model, rec.u, rec.dt))
sd = r["noise_sd"]
e = yh - rec.y
print("train", np.sqrt(np.mean(e[:h0] ** 2)) / sd, "held", np.sqrt(np.mean(e[h0:] ** 2)) / sd, "s", time.time() - t0)
sj.save_model(out.replace(".npz", ".json"), model)
np.savez(out, u=rec.u, y=rec.y, y_clean=r["y_clean"], yh=yh, dt=rec.dt, h0=h0, sd=sd, x_h=r["sim"]["x_h"],
         theta=r["sim"].get("theta", np.zeros(1)))
json.dump({"truth": r["truth"], "meta": r["meta"], "doc_settings": doc["settings"], "notes": doc.get("notes")},
          open(out.replace(".npz", "_doc.json"), "w"), indent=1, default=str)
