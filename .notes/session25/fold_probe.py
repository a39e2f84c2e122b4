import sys
import numpy as np
sys.path[:0] = ["/work/main", "/work/main/experiments"]
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import diagnose, fit_extended
from smafl_jax.diagnosis._diagnose import fold_splits, _held, refine_model, _context  # private: probe
path, case = ie.write_effect_record("/tmp/s25_probe", "output_lag", 8001 - 8000)
print(case["effect_params"], case["rate_hz"], case["drive"], case["start"])
rec = sj.load_record(path)
d = diagnose(rec, effects=["output_lag"], refit=False, verbose=False, n_null=2, unexplained=False)
base = d.base
for j, fs in enumerate(fold_splits(rec, 3)):
    cb, _ = fit_extended(base, [], fs)
    cm, _ = fit_extended(base, ["output_lag"], fs)
    print(j, "ctx duration", _context(fs)["duration"], "tau", float(cm.get("output_lag").tau), "base", _held(cb, fs)["rmse"], "lag", _held(cm, fs)["rmse"])
    h = getattr(cm.base, "hysteresis", None)
    if j == 0:
        yb = np.asarray(sj.simulate(cb, rec.u, rec.dt)); ym = np.asarray(sj.simulate(cm, rec.u, rec.dt))
        e = ym - rec.y
        print("  error by 100-sample block (lag model):", np.round([np.sqrt(np.mean(e[i:i+100]**2)) for i in range(0, 1100, 100)], 3))
        print("  thermal", cb.base.thermal if hasattr(cb, "base") else None)
        print("  lag model thermal", cm.base.thermal)
