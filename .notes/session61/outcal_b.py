import sys, numpy as np
sys.path.insert(0, "/work/main/experiments")
import indep_plant_b as pb, fit_plant_b as fpb
res = []
for c in fpb.grid([int(s) for s in sys.argv[1:]], 10.0):
    kw = {k: v for k, v in c.items() if k != "seed"}
    r = pb.make_record(c["seed"], **kw)
    y = np.asarray(r["output_clean"]); h0 = r["heldout_start"]
    lo, hi = y[:h0].min(), y[:h0].max(); span = hi - lo
    ex = max(y[h0:].max() - hi, lo - y[h0:].min(), 0) / span
    res.append(ex); print(fpb.name_of(c), f"{ex:.3f}", f"T-in {r['truth']['heldout_T_inside_fraction']:.2f}", flush=True)
print("max", max(res))
