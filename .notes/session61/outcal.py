"""How far a plant's own held-out output leaves the output range of its training part (units of that span)."""
import sys, json, subprocess, numpy as np
sys.path.insert(0, "/work/main/tests"); sys.path.insert(0, "/work/main/.notes/session48"); sys.path.insert(0, "/work/main/experiments")
import indep_plant as ip
import random_cells as rc
res = []
for seed in range(int(sys.argv[1]), int(sys.argv[2])):
    line = subprocess.run([sys.executable, "/work/main/.notes/session48/random_cells.py", str(seed)], capture_output=True, text=True).stdout.split("\t")
    minutes = float(line[1]); (name, kw), = json.loads(line[2]).items()
    r = ip.make_record(seed, minutes=minutes, **kw)
    y = r["y_clean"]; h0 = r["heldout_start"]
    lo, hi = y[:h0].min(), y[:h0].max(); span = hi - lo
    ex = max(y[h0:].max() - hi, lo - y[h0:].min(), 0) / span
    res.append(ex); print(seed, name, f"{ex:.3f}", flush=True)
print("max", max(res), "p90", np.percentile(res, 90))
