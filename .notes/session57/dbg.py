"""Debug the warm-start slow fit on one plant D record: one-mode vs slow (warm) per stage."""
import sys, tempfile
from pathlib import Path
import numpy as np
ROOT = Path("/work/main")
sys.path.insert(0, str(ROOT / "experiments")); sys.path.insert(0, str(ROOT))
import indep_plant_d as pd
import smafl_jax as sj
from smafl_jax.report import _report_fit as rf
from smafl_jax.data.split import *  # noqa
seed, cell, model = int(sys.argv[1]), sys.argv[2], sys.argv[3]
drive, rate, start, sensor = cell.split(":")
r = pd.make_record(seed, drive=drive, rate_hz=float(rate), minutes=10, start=start, sensor=sensor, physics=("sleeve",))
h0, sd = r["heldout_start"], r["noise_sd"]
tmp = tempfile.mkdtemp()
rec = sj.load_record(pd.write_csv(Path(tmp) / "d.csv", r, stop=h0))
print("truth", {k: r["truth"]["wire"][k] for k in ("tau_wire_s", "tau_sleeve_s", "sleeve_share")})
from smafl_jax.identify._split import split_masks
tr, va, info = split_masks(rec, "auto", val_fraction=0.3)
print("split", info.get("kind"), tr.sum(), va.sum())
c1 = rf._fit_structure(rec, model=model, defer_refit=True, thresholds=True, tilts=True)
def rm(m, mask):
    y = np.asarray(sj.simulate(m, rec.u, rec.dt)); return float(np.sqrt(np.mean((y[mask]-rec.y[mask])**2)))
print("one-mode", c1.metrics["train"]["rmse"], c1.metrics["validation"]["rmse"], float(c1.model.thermal.k1))
w = rf.slow_warm_start(c1.model, rec, [tr.astype(float)])
th = w.thermal
print("warm NM", rm(w, tr), rm(w, va), float(th.k1), 1/float(th.slow_k1), float(th.slow_ratio)/(1+float(th.slow_ratio)))
c2 = rf._fit_structure(rec, model=model, defer_refit=True, thresholds=True, tilts=True, slow_mode=True, warm_start=c1.model, progress=True)
th = c2.model.thermal
print("slow fit", c2.metrics["train"]["rmse"], c2.metrics["validation"]["rmse"], float(th.k1), 1/float(th.slow_k1), float(th.slow_ratio)/(1+float(th.slow_ratio)))
for n in c2.finish()[1]["notes"]:
    print(" -", n[:300])
