import json, sys, os, numpy as np
import smafl_jax as sj
from smafl_jax.identify import linear  # private: DEAD_RTOL probe
sys.path.insert(0, "/work/main/experiments")
import indep_plant_c as pc, plant_c_trial as T
meta = pc.make_record(*T.RECORDS["r10"])[4]
news = {}
for new in ["r10c", "r10d"]:
    os.environ["PLANT_C_OFFSET"] = repr(meta["offset_mm"])
    t, u, meas, clean, m = pc.make_record(*T.NEW_RUNS[new][1]); os.environ.pop("PLANT_C_OFFSET")
    news[new] = (u, clean, m["noise_sd"], t[1] - t[0])
d = json.load(open(sys.argv[1])); model = sj.model_from_dict(d["model"])
rec = sj.load_record("/tmp/s44/pc/r10/r10_first70.csv")
for rtol in [1e-9, 1e-3, 1e-2, 3e-2]:
    linear.DEAD_RTOL = rtol
    res = sj.fit(model, rec, solver=None, init=None, gain_prior=float(sys.argv[2]))
    mm = res.model
    yh = np.asarray(sj.simulate(mm, rec.u, rec.dt)); tr = np.sqrt(np.mean((yh - rec.y) ** 2)) / 0.01876
    out = []
    for new, (u, clean, sd, dt) in news.items():
        y = np.asarray(sj.simulate(mm, u, dt)); out.append(np.sqrt(np.mean((y - clean) ** 2)) / sd)
    print(rtol, "train %.3f" % tr, "new runs", ["%.1f" % o for o in out])
