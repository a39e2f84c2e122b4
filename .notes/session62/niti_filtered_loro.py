import sys, json, numpy as np
sys.path.insert(0, "/work/main")
import smafl_jax as sj
from smafl_jax.identify._baselines import fit_static_poly
D = "/work/shared/data/real/"
names = [f"niti_wire_electric_0{i}.csv" for i in range(1, 6)]
def lag(T,a):
    x=np.empty_like(T); s=T[0]
    for i,v in enumerate(T): s=s+a*(v-s); x[i]=s
    return x
raw = {n: sj.load_record(D + n, input="temperature_front_C", output="length_signal") for n in names}
for a in [float(x) for x in sys.argv[1:]]:
    recs = {n: sj.Record.from_arrays(r.time, lag(np.asarray(r.u), a), r.y, input_name="temperature_C", output_name="length") for n, r in raw.items()}
    rat = []
    for test in names:
        train = [recs[n] for n in names if n != test]
        model, doc, _ = sj.fit_records(train, split="none")
        R = recs[test]; yh = np.asarray(sj.simulate(model, R.u, R.dt))
        rm = float(np.sqrt(np.mean((yh - R.y) ** 2)))
        # baseline: the cubic of the raw temperature, held (session 61's comparison is the plain cubic)
        trr = [raw[n] for n in names if n != test]; Rr = raw[test]
        yp = np.asarray(fit_static_poly(trr, order=3).predict(Rr.u, Rr.dt)); rp = float(np.sqrt(np.mean((yp - Rr.y) ** 2)))
        rat.append(rm / rp); print(a, test, doc["settings"].get("structure"), round(rm, 3), round(rp, 3), flush=True)
    print("a", a, "gm ratio %.3f" % np.exp(np.mean(np.log(rat))), flush=True)
