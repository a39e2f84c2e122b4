"""Probe: plant A cell fitted on a grid that holds the plant's own thresholds and tilts (oracle), one-mode cascade."""
import sys, json, time
import numpy as np
import smafl_jax as sj
import smafl_jax.models._eupi as E
from smafl_jax.report import fit_record

full, part = sys.argv[1:3]
truth = json.load(open(full.replace(".csv", ".truth.json")))
hy = truth["truth"]["hysteresis"]
r, a = np.array(hy["r"]), np.array(hy["alpha"])
ns = hy["n_sym"]
r_sym, r_asym, al = r[:ns], np.sort(r[ns:]), np.sort(a[ns:])
print("oracle r_sym", r_sym, "r_asym", r_asym, "alpha", al)
E.threshold_grid = lambda n: r_sym.copy() if int(n) == len(r_sym) else r_asym.copy()
E.tilt_grid = lambda n, lo=0.4, hi=2.5: al.copy()
rec, p70 = sj.load_record(full), sj.load_record(part)
t0 = time.time()
m, doc, _ = fit_record(p70, model="cascade", slow_mode="off", grid={"n_sym": len(r_sym), "n_asym": len(r_asym), "n_alpha": len(al), "poly_order": 3})
yh = np.asarray(sj.simulate(m, rec.u, rec.dt))
e = yh - rec.y; h0 = truth["heldout_start"]; sd = truth["noise_sd"]
print(json.dumps(dict(kind="oracle", train=float(np.sqrt(np.mean(e[:h0] ** 2)) / sd), held=float(np.sqrt(np.mean(e[h0:] ** 2)) / sd),
      val=(doc["metrics"].get("validation") or {}).get("rmse", np.nan) / sd, seconds=time.time() - t0, memory=doc["settings"].get("memory_used"), sees=str(doc["model"].get("sees")))))
