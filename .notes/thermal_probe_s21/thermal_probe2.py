import sys, json, time, numpy as np
import smafl_jax as sj
from smafl_jax.diagnosis._diagnose import fit_extended, make_split, score  # private: probe
import glob, os
for prefix in sys.argv[1:]:
    d = sorted(glob.glob(f"/tmp/cf_work/{prefix}*"))[0]; name = os.path.basename(d)
    z = np.load(f"{d}/full.npz"); sd = float(z["sd"]); dt = float(z["dt"])
    t = np.arange(len(z["u"])) * dt
    sj.atomic_write_csv(f"{d}/full.csv", {"time_s": t, "voltage_V": z["u"], "displacement_mm": z["y"]})
    rec = sj.load_record(f"{d}/full.csv"); split = make_split(rec)
    m = sj.load_model(f"{d}/fit_P/fit.json")
    for effs in ([], ["resistance_tc", "nonlinear_cooling"]):
        t0 = time.perf_counter()
        try:
            fm, info = fit_extended(m, effs, split)
            tr = score(fm, split.train)[0]["rmse"] / sd; he = score(fm, split.test)[0]["rmse"] / sd
            print(json.dumps({"name": name, "effects": effs, "train_x": round(tr, 2), "held_x": round(he, 2), "s": round(time.perf_counter() - t0)}), flush=True)
        except Exception as ex:  # probe: report and go on
            print(json.dumps({"name": name, "effects": effs, "error": repr(ex)[:200]}), flush=True)
