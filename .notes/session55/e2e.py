import sys, json, numpy as np
sys.path.insert(0, "/work/main/experiments"); sys.path.insert(0, "/work/main/tests")
import class_choice_coverage as ccc, smafl_jax as sj
from smafl_jax.report import fit_record
cell, seed = sys.argv[1], int(sys.argv[2])
p, h0, sd = ccc._record("b", seed, ccc.CELLS_B[cell], folder=__import__("pathlib").Path("/tmp/s55"))
rec = sj.load_record(p)
p70 = p.with_name(p.stem + "_70.csv")
sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
m, doc, _ = fit_record(sj.load_record(p70))
e = np.asarray(sj.simulate(m, rec.u, rec.dt)) - rec.y
ch = doc["settings"]["structure_choice"]
print(cell, seed, "chosen", ch["chosen"], "check", json.dumps(ch.get("whole_record_check", {}).get("whole_record_rmse")), ch.get("whole_record_check", {}).get("switched"),
      "train", round(float(np.sqrt(np.mean(e[:h0]**2))/sd),2), "held", round(float(np.sqrt(np.mean(e[h0:]**2))/sd),2), flush=True)
