"""Branch coverage of the plant's TRUE hysteresis input (held-out vs training part) per random cell, with the default
fit's held-out error from the stored rows: are the misses extrapolations to untrained branches of the plant's state?"""
import sys, json, glob, subprocess
sys.path.insert(0, "/work/main/tests")
import numpy as np
import indep_plant as ip
from smafl_jax.data.split import branch_coverage
rows = {}
for d in sys.argv[1:]:
    for p in glob.glob(d + "/s*.json"):
        for r in json.load(open(p)):
            rows[r["seed"]] = r
out = []
for s in sorted(rows):
    line = subprocess.check_output([sys.executable, "/work/main/.notes/session48/random_cells.py", str(s)], text=True).strip()
    minutes, cell = float(line.split("\t")[1]), json.loads(line.split("\t")[2])
    kw = next(iter(cell.values()))
    r = ip.make_record(s, minutes=minutes, **kw)
    h0 = r["heldout_start"]; x = np.asarray(r["sim"]["x_h"], float); n = x.size
    tr = np.arange(n) < h0; te = ~tr
    c = branch_coverage(x, tr, te)
    xin = float(np.mean((x[te] >= x[tr].min()) & (x[te] <= x[tr].max())))
    rw = rows[s]
    out.append((c["covered_fraction"], rw["held"], rw["train"], s, rw["cell"], xin, rw.get("memory")))
    print(f"{s} cov {c['covered_fraction']:.3f} x-in-range {xin:.3f} held {rw['held']:6.2f} train {rw['train']:.2f} {rw['cell']}", flush=True)
print()
for lo, hi in ((0.95, 1.01), (0.9, 0.95), (0.7, 0.9), (0.0, 0.7)):
    g = [o for o in out if lo <= o[0] < hi]
    if g:
        h = np.array([o[1] for o in g])
        print(f"coverage [{lo}, {hi}): {len(g)} cells, gm held {np.exp(np.mean(np.log(h))):.2f}, within 1.5x {int((h <= 1.5).sum())}, within 3x {int((h <= 3).sum())}")
