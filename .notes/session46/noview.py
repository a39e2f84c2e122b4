"""Probe: plant-B 100 Hz record refitted without the decimated view (DECIMATE_ABOVE raised)."""
import sys, time, json, numpy as np
import smafl_jax as sj
from smafl_jax.identify import _decimate  # private: probe
from smafl_jax.report import fit_record
name, mode = sys.argv[1], sys.argv[2]
d = f"/tmp/s46/pb{name[1:3]}/{name}"
if mode == "noview":
    _decimate.DECIMATE_ABOVE = 10**9
elif mode.startswith("stride"):
    _decimate.MAX_STRIDE = int(mode[6:])
tr = sj.load_record(f"{d}/first70.csv"); full = sj.load_record(f"{d}/full.csv")
t0 = time.time(); model, doc, _ = fit_record(tr); sec = time.time() - t0
y = np.asarray(sj.simulate(model, full.u, full.dt)); h0 = len(tr)
r = lambda e: float(np.sqrt(np.mean(e**2))) / 0.005
print(json.dumps({"name": name, "mode": mode, "train": r(y[:h0] - full.y[:h0]), "held": r(y[h0:] - full.y[h0:]), "chosen": doc["settings"].get("structure_choice", {}).get("chosen"), "seconds": sec}))
