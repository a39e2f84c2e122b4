import sys, json, time
from pathlib import Path
sys.path.insert(0, "/work/main/tests")
import numpy as np
import indep_plant as ip
import smafl_jax as sj
seed, sees, out = int(sys.argv[1]), sys.argv[2], sys.argv[3]
drives = sys.argv[4].split(",") if len(sys.argv) > 4 else ["pwm", "multisine", "steps"]
recs, sds, truth = [], [], None
for d in drives:
    r = ip.make_record(seed, drive=d, rate_hz=25, minutes=6.0, start="cold")
    p = Path(f"/tmp/s50/multi/s{seed}_{d}.csv"); ip.write_csv(p, r)
    recs.append(sj.load_record(p)); sds.append(r["noise_sd"]); truth = r["truth"]["hysteresis"]["input"]
t0 = time.time()
model, doc, det = sj.fit_records(recs, sees=sees, model="cascade")
import json as _j
open(out + f".{seed}_{sees}.doc.json", "w").write(_j.dumps(doc, default=str))
loro = [f["model"]["rmse"] / sd if f["model"] else None for f, sd in zip(doc["validation"]["folds"], sds)]
row = {"seed": seed, "sees": sees, "truth": truth, "chosen": getattr(model, "sees", None), "loro": loro,
       "train": [m["rmse"] / sd for m, sd in zip(doc["per_record_train"].values(), sds)],
       "seconds": time.time() - t0}
print(json.dumps(row)); open(out, "a").write(json.dumps(row) + "\n")
