import sys, json, time, numpy as np, pathlib
sys.path.insert(0, "/work/main/experiments"); sys.path.insert(0, "/work/main/tests")
import class_choice_coverage as ccc, smafl_jax as sj
from smafl_jax.report import fit_record
out, slow = sys.argv[1], sys.argv[2]
todo = [a.split(":") for a in sys.argv[3:]]  # seed:cell-index
for seed, ci in todo:
    cell = list(ccc.CELLS_B)[int(ci)]; seed = int(seed)
    p, h0, sd = ccc._record("b", seed, ccc.CELLS_B[cell], folder=pathlib.Path("/tmp/s56/b"))
    rec = sj.load_record(p)
    p70 = p.with_name(p.stem + "_70.csv")
    sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
    t0 = time.perf_counter()
    m, doc, _ = fit_record(sj.load_record(p70), slow_mode=slow)
    sec = time.perf_counter() - t0
    e = np.asarray(sj.simulate(m, rec.u, rec.dt)) - rec.y
    ch = doc["settings"]["structure_choice"]
    row = dict(seed=seed, cell=cell, slow=slow, chosen=ch["chosen"], wrc=ch.get("whole_record_check"), smc=ch.get("slow_mode_check"),
               train=float(np.sqrt(np.mean(e[:h0]**2))/sd), held=float(np.sqrt(np.mean(e[h0:]**2))/sd), seconds=sec)
    open(out, "a").write(json.dumps(row) + "\n")
    print(seed, cell, slow, row["chosen"], "train %.2f held %.2f" % (row["train"], row["held"]), "slow", None if row["smc"] is None else row["smc"]["kept"], "%.0f s" % sec, flush=True)
