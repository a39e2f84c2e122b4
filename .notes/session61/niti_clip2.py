import sys, json, numpy as np
sys.path.insert(0, "/tmp/s61")
import smafl_jax as sj
from clip_probe_lib import sim_clipped, sim_ops_held
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
        a = e(sj.simulate(model, R.u, R.dt)); b = e(sim_clipped(model, R.u, R.dt, (lo, hi))); b2 = e(sim_ops_held(model, R.u, R.dt, (lo, hi)))
        cub = fit_static_poly(train, order=3)
        c = e(cub.predict(R.u, R.dt)); c2 = e(cub.predict(np.clip(R.u, lo, hi), R.dt))
        rs.append((a / c, b / c, b2 / c, b / c2))
        print(f"{fam} {test} model {a:.2f} all-held {b:.2f} ops-held {b2:.2f} cubic {c:.2f} cubic-held {c2:.2f}", flush=True)
    g = np.exp(np.mean(np.log(rs), axis=0)); print(fam, "gm ratio: as is %.3f all-held %.3f ops-held %.3f; all-held vs held cubic %.3f" % tuple(g))
