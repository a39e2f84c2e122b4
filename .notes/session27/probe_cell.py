"""Session 27 probe: default (or given) fit_record of one plant-A record on its first 70 %, scored on the rest.
    MIN=5 PROG=1 python probe_cell.py SEED 'CELL NAME or JSON of make_record keywords' ['{"model": "cascade"}']
Writes e_SEED.npy (time, u, y, model output) for error_by_time.py."""
import sys, json, time
sys.path.insert(0, "/work/main/tests")
import numpy as np, indep_plant as ip, smafl_jax as sj
from smafl_jax.report import fit_record
seed = int(sys.argv[1]); cell = sys.argv[2]; opts = json.loads(sys.argv[3]) if len(sys.argv) > 3 else {}
kw = ip.MATRIX_CELLS[cell] if cell in ip.MATRIX_CELLS else json.loads(cell)
r = ip.make_record(seed, minutes=float(__import__("os").environ.get("MIN", 10)), **kw)
t = r["truth"]
print({k: t[k] for k in t if k not in ("drive",)} if False else sorted(t.keys()))
for k in ("thermal", "hyst", "memory", "sensor", "orientation"):
    if k in t: print(k, json.dumps(t[k], default=str)[:600])
h0 = r["heldout_start"]; sd = r["noise_sd"]
p = f"/tmp/s27/p11/m_{seed}.csv"; ip.write_csv(p, r); rec = sj.load_record(p)
p70 = f"/tmp/s27/p11/m70_{seed}.csv"
sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
t0 = time.time()
model, doc, _ = fit_record(sj.load_record(p70), progress=bool(int(__import__("os").environ.get("PROG", 0))), **opts)
e = np.asarray(sj.simulate(model, rec.u, rec.dt)) - rec.y
print("sec", round(time.time()-t0), "train", np.sqrt(np.mean(e[:h0]**2))/sd, "held", np.sqrt(np.mean(e[h0:]**2))/sd)
print(json.dumps(doc["settings"].get("structure_choice"), default=str)[:1500])
print(json.dumps({k: doc["settings"].get(k) for k in ("memory", "start", "initial_state")}, default=str)[:1500])
print(model)
np.save(f"/tmp/s27/p11/e_{seed}.npy", np.c_[rec.time, rec.u, rec.y, np.asarray(sj.simulate(model, rec.u, rec.dt))])
th = model.thermal; print("k1", float(th.k1), "k2", float(th.k2), "u0", float(th.u0))
