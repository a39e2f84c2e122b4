"""Where does a warm slow fit lose validation? instrument _polish and refine gate."""
import sys, tempfile
from pathlib import Path
import numpy as np
ROOT = Path("/work/main")
sys.path.insert(0, str(ROOT / "experiments")); sys.path.insert(0, str(ROOT))
import indep_plant_d as pd
import smafl_jax as sj
from smafl_jax.report import _report_fit as rf
from smafl_jax.identify._split import split_masks
seed, cell, model = int(sys.argv[1]), sys.argv[2], sys.argv[3]
drive, rate, start, sensor = cell.split(":")
r = pd.make_record(seed, drive=drive, rate_hz=float(rate), minutes=10, start=start, sensor=sensor, physics=("sleeve",))
h0, sd = r["heldout_start"], r["noise_sd"]
rec = sj.load_record(pd.write_csv(Path(tempfile.mkdtemp()) / "d.csv", r, stop=h0))
print("truth", {k: r["truth"]["wire"][k] for k in ("tau_wire_s", "tau_sleeve_s", "sleeve_share")})
tr, va, info = split_masks(rec, "auto", val_fraction=0.3)
def rm(m, mask):
    y = np.asarray(sj.simulate(m, rec.u, rec.dt)); return float(np.sqrt(np.mean((y[mask]-rec.y[mask])**2)))
def desc(m):
    th = m.thermal
    return f"k1 {float(th.k1):.3g}" + (f" slow {1/float(th.slow_k1):.3g}s {float(th.slow_ratio)/(1+float(th.slow_ratio)):.3f}" if th.has_slow_mode else "")
orig = rf._polish
def pol(model, record, mask, *a, **k):
    out = orig(model, record, mask, *a, **k)
    if len(record) == len(rec):
        print(f"  POLISH: train {rm(model,tr):.4g}->{rm(out,tr):.4g} val {rm(model,va):.4g}->{rm(out,va):.4g}  {desc(model)} -> {desc(out)}", flush=True)
    return out
rf._polish = pol
c1 = rf._fit_structure(rec, model=model, defer_refit=True, thresholds=True, tilts=True)
print("one-mode", c1.metrics["train"]["rmse"], c1.metrics["validation"]["rmse"], desc(c1.model))
w = rf.slow_warm_start(c1.model, rec, [tr.astype(float)])
print("warm NM (full-rate record)", rm(w, tr), rm(w, va), desc(w))
c2 = rf._fit_structure(rec, model=model, defer_refit=True, thresholds=True, tilts=True, slow_mode=True, warm_start=c1.model)
print("slow fit", c2.metrics["train"]["rmse"], c2.metrics["validation"]["rmse"], desc(c2.model))
if len(sys.argv) > 4:
    c3 = rf._fit_structure(rec, model=model, defer_refit=True, thresholds=True, tilts=True, slow_mode=True)
    print("fresh slow fit", c3.metrics["train"]["rmse"], c3.metrics["validation"]["rmse"], desc(c3.model))
