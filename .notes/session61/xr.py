import sys, json, subprocess, numpy as np
sys.path.insert(0, "/work/main/tests")
import indep_plant as ip, copy
for seed in map(int, sys.argv[1:]):
    line = subprocess.run([sys.executable, "/work/main/.notes/session48/random_cells.py", str(seed)], capture_output=True, text=True).stdout.split("\t")
    minutes = float(line[1]); (name, kw), = json.loads(line[2]).items()
    r = ip.make_record(seed, minutes=minutes, **kw)
    t = copy.deepcopy(r["truth"]); t["effect"] = None
    x = ip._core(t, r["u"] if "u" in r else np.asarray(r["voltage_V"]), 1.0 / kw["rate_hz"], upto="x")["x_h"]
    h0 = r["heldout_start"]
    lo, hi = x[:h0].min(), x[:h0].max(); ptp = hi - lo
    print(seed, name, f"train x [{lo:.4f},{hi:.4f}] held [{x[h0:].min():.4f},{x[h0:].max():.4f}] over top {(x[h0:].max()-hi)/ptp*100:.2f}% under {(lo-x[h0:].min())/ptp*100:.2f}%; first over at {np.argmax(x[h0:]>hi)/(len(x)-h0):.2f} of held")
