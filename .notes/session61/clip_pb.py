"""Plant B fits (fit_plant_b work dirs): held-out error as is and with the hysteresis input held to its trained range."""
import sys, json, glob, re
from pathlib import Path
import numpy as np
import smafl_jax as sj
sys.path.insert(0, "/tmp/s61"); from clip_probe_lib import sim_clipped
rows = []
for d in sorted(glob.glob(sys.argv[1])):
    d = Path(d); fj = next(d.rglob("fit.json"), None)
    if fj is None: continue
    doc = json.loads(fj.read_text()); model = sj.load_model(fj)
    tr = sj.load_record(d / "first70.csv"); full = sj.load_record(d / "full.csv"); h0 = len(tr)
    sd = float(re.search(r"_n([0-9.]+)", d.name).group(1))
    rng = doc["data"].get("effective_input_range") or doc["data"]["input_range"]
    ya = np.asarray(sj.simulate(model, full.u, full.dt)); yb = sim_clipped(model, full.u, full.dt, rng)
    a = np.sqrt(np.mean((ya[h0:] - full.y[h0:]) ** 2)) / sd
    b = np.sqrt(np.mean((yb[h0:] - full.y[h0:]) ** 2)) / sd if yb is not None else float("nan")
    rows.append((a, b)); print(f"{d.name:40s} {type(model).__name__:14s} as is {a:8.2f} clipped {b:8.2f}", flush=True)
r = np.array([x for x in rows if np.isfinite(x[1])])
print("n", len(r), "gm as is %.2f clipped %.2f" % tuple(np.exp(np.mean(np.log(r), axis=0))))
