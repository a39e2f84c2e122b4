"""LORO of the default joint fit on the NiTi families, one code root (grid comparison, session 60).

python .notes/session60/niti_loro_probe.py ROOT OUT.json
Each held-out record: `fit_records(other records of its family, split="none")`, simulated free-run over it; RMSE and
the ratio to a static cubic of the temperature fitted on the same training records.
"""
import json, sys, time
sys.path.insert(0, sys.argv[1])
import numpy as np
import smafl_jax as sj
from smafl_jax.identify._baselines import fit_static_poly

D = "/work/shared/data/real/"
FAM = {"electric": [f"niti_wire_electric_0{i}.csv" for i in range(1, 6)],
       "water": [f"niti_wire_water_step_0{i}.csv" for i in range(1, 5)],
       "cavatappi": [f"cavatappi_pneumatic_200g_{s}.csv" for s in ("s1_t1", "s1_t2", "s2_t1", "s3_t1")]}
rows = []
for fam, names in FAM.items():
    kw = dict(input="pressure", output="displacement_mm", resample=0.01) if fam == "cavatappi" else dict(input="temperature_front_C", output="length_signal")
    recs = {n: sj.load_record(D + n, **kw) for n in names}
    for test in names:
        train = [recs[n] for n in names if n != test]
        t0 = time.time()
        model, doc, _ = sj.fit_records(train, split="none")
        R = recs[test]
        yh = np.asarray(sj.simulate(model, R.u, R.dt))
        ok = R.measured & np.isfinite(R.y); rmse = float(np.sqrt(np.mean((yh[ok] - R.y[ok]) ** 2)))
        yp = fit_static_poly(train, order=3).predict(R.u, R.dt)
        rp = float(np.sqrt(np.mean((np.asarray(yp)[ok] - R.y[ok]) ** 2)))
        row = dict(family=fam, test=test, structure=doc["settings"].get("structure"), held=getattr(getattr(model, "hysteresis", model), "held", None), rmse=rmse, poly3=rp, ratio=rmse / rp, seconds=time.time() - t0)
        print(json.dumps(row), flush=True)
        rows.append(row)
json.dump(rows, open(sys.argv[2], "w"), indent=1)
