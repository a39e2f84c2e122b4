import sys, numpy as np
sys.path.insert(0, "/work/main/experiments")
import indep_plant_b as pb, fit_plant_b as fpb
for c in fpb.grid([int(s) for s in sys.argv[1:]], 10.0):
    kw = {k: v for k, v in c.items() if k != "seed"}
    r = pb.make_record(c["seed"], **kw)
    y = np.asarray(r["output_clean"]); h0 = r["heldout_start"]; T = np.asarray(r["truth"]["temperature"])
    def ex(v):
        lo, hi = v[:h0].min(), v[:h0].max(); return max(v[h0:].max() - hi, lo - v[h0:].min(), 0) / (hi - lo)
    print(fpb.name_of(c), f"out {ex(y):.3f} T {ex(T):.3f} ratio {ex(y)/max(ex(T),1e-9):.1f}", flush=True)
