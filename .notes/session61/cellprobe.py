"""One fresh cell: fit the first 70 %, then where the held-out error comes from (windows, input range, heat)."""
import sys, json, pickle, time
from pathlib import Path
root = Path(sys.argv[1]).resolve(); seed = int(sys.argv[2])
sys.path.insert(0, str(root)); sys.path.insert(0, "/work/main/tests"); sys.path.insert(0, "/work/main/.notes/session48")
import numpy as np, indep_plant as ip, smafl_jax as sj
from smafl_jax.report import fit_record
import subprocess
line = subprocess.run([sys.executable, "/work/main/.notes/session48/random_cells.py", str(seed)], capture_output=True, text=True).stdout.split("\t")
minutes = float(line[1]); (name, kw), = json.loads(line[2]).items()
r = ip.make_record(seed, minutes=minutes, **kw)
h0 = r["heldout_start"]; sd = r["noise_sd"]
p = f"/tmp/s61/rec_{seed}.csv"; ip.write_csv(p, r); rec = sj.load_record(p)
p70 = f"/tmp/s61/rec70_{seed}.csv"
sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
opts = json.loads(sys.argv[3]) if len(sys.argv) > 3 else {}
t0 = time.time(); model, doc, _ = fit_record(sj.load_record(p70), **opts); sec = time.time() - t0
yh = np.asarray(sj.simulate(model, rec.u, rec.dt)); e = yh - rec.y
print(name, "train", np.sqrt(np.mean(e[:h0]**2))/sd, "held", np.sqrt(np.mean(e[h0:]**2))/sd, f"{sec:.0f} s")
print("truth", json.dumps(r["truth"], default=str)[:1500])
u = rec.u; n = len(u)
print("u range train", u[:h0].min(), u[:h0].max(), "held", u[h0:].min(), u[h0:].max())
w = n // 20
for i in range(20):
    sl = slice(i*w, (i+1)*w)
    print(f"win {i:2d} {'H' if i*w>=h0 else 'T'} rmse/sd {np.sqrt(np.mean(e[sl]**2))/sd:7.2f} mean/sd {np.mean(e[sl])/sd:7.2f} u mean {u[sl].mean():.3f} y mean {rec.y[sl].mean():.3f}")
for nt in doc.get("notes", []): print("NOTE", nt[:400])
pickle.dump(dict(yh=yh, y=rec.y, u=u, h0=h0, sd=sd), open(f"/tmp/s61/probe_{seed}.pkl", "wb"))
