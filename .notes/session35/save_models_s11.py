import sys, numpy as np, time, json
import smafl_jax as sj
from smafl_jax.report import fit_record
tag = "11_pwm"
d = np.load(f"/tmp/s35_{tag}.npz"); h0 = int(d["h0"])
rec = sj.load_record(f"/tmp/s35_{tag}.csv"); r70 = sj.load_record(f"/tmp/s35_{tag}_70.csv")
out = {}
for nm, r in (("full", rec), ("p70", r70)):
    model, doc, _ = fit_record(r, split="none")
    sj.save_model(f"/tmp/s35_{tag}_{nm}.json", model)
    yh = np.asarray(sj.simulate(model, rec.u, rec.dt)); e = yh - rec.y
    print(nm, "train %.3f held %.3f" % (np.sqrt(np.mean(e[:h0]**2))/0.005, np.sqrt(np.mean(e[h0:]**2))/0.005))
    m = model
    print(" k1 %.5f k2 %.5f u0 %.4f" % (m.thermal.k1, m.thermal.k2, m.thermal.u0))
    h = m.hysteresis
    for f in ("gain", "v", "w", "poly", "offset", "r_sym", "r_asym", "alpha", "u_ref", "u_span"):
        print(" ", f, np.round(np.asarray(getattr(h, f)), 4).tolist())
    print(" memory", json.dumps(doc["settings"].get("memory"), default=str)[:300], doc["settings"].get("start_screening", [{}])[-1] if False else "")
