"""NiTi LORO: the joint fit's free-run on the held-out run as is, and with its input clipped to the trained range."""
import sys, json, numpy as np
import smafl_jax as sj
from smafl_jax.identify._baselines import fit_static_poly
D = "/work/shared/data/real/"
FAM = {"electric": [f"niti_wire_electric_0{i}.csv" for i in range(1, 6)],
       "water": [f"niti_wire_water_step_0{i}.csv" for i in range(1, 5)]}
for fam, names in FAM.items():
    recs = {n: sj.load_record(D + n, input="temperature_front_C", output="length_signal") for n in names}
    rs = []
    for test in names:
        train = [recs[n] for n in names if n != test]
        model, doc, _ = sj.fit_records(train, split="none")
        R = recs[test]
        lo = min(r.u.min() for r in train); hi = max(r.u.max() for r in train)
        e = lambda p: float(np.sqrt(np.mean((np.asarray(p) - R.y) ** 2)))
        a = e(sj.simulate(model, R.u, R.dt)); b = e(sj.simulate(model, np.clip(R.u, lo, hi), R.dt))
        c = e(fit_static_poly(train, order=3).predict(R.u, R.dt))
        out = float(np.mean((R.u < lo) | (R.u > hi)))
        rs.append((a / c, b / c))
        print(f"{fam} {test} out {out:.3f} model {a:.2f} clipped {b:.2f} cubic {c:.2f}", flush=True)
    g = np.exp(np.mean(np.log(rs), axis=0)); print(fam, "gm ratio to cubic: as is %.3f clipped %.3f" % tuple(g))
