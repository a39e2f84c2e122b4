import sys, numpy as np, json
import smafl_jax as sj
from smafl_jax.identify._baselines import fit_static_poly
D = "/work/shared/data/real/"
names = [f"niti_wire_water_step_0{i}.csv" for i in range(1, 5)]
recs = {n: sj.load_record(D + n, input="temperature_front_C", output="length_signal") for n in names}
test = names[1]
train = [recs[n] for n in names if n != test]
model, doc, _ = sj.fit_records(train, split="none")
print(doc["settings"].get("structure"), type(model).__name__)
R = recs[test]
yh = np.asarray(sj.simulate(model, R.u, R.dt)); yp = np.asarray(fit_static_poly(train, order=3).predict(R.u, R.dt))
lo = min(r.u.min() for r in train); hi = max(r.u.max() for r in train)
out = (R.u < lo) | (R.u > hi)
print("trained T range", lo, hi, "outside frac", out.mean())
for name, p in (("model", yh), ("cubic", yp)):
    e = p - R.y
    print(name, "all %.2f inside %.2f outside %.2f" % (np.sqrt(np.mean(e**2)), np.sqrt(np.mean(e[~out]**2)), np.sqrt(np.mean(e[out]**2)) if out.any() else 0))
n = len(R.u); w = n // 19
for i in range(19):
    s = slice(i*w, (i+1)*w)
    print(f"{i:2d} T {R.u[s].min():6.1f}-{R.u[s].max():5.1f} y {R.y[s].mean():6.2f} model {yh[s].mean():6.2f} cubic {yp[s].mean():6.2f} out {out[s].mean():.2f}")
np.savez("/tmp/s61/w2.npz", u=R.u, y=R.y, yh=yh, yp=yp)
