"""Turning-point coverage of the plant's TRUE hysteresis input: a held-out sample is covered when a training sample has the
same branch direction, a value within tol x span and a last turning point within ttol x span."""
import sys, json, glob, subprocess
sys.path.insert(0, "/work/main/tests")
import numpy as np
import indep_plant as ip
from smafl_jax.data.split import branch_directions

def last_turn(x, d):
    t = np.empty_like(x); cur = x[0]; prev = 0
    for k in range(x.size):
        if d[k] != 0 and d[k] != prev and prev != 0:
            cur = x[k - 1]
        if d[k] != 0:
            prev = d[k]
        t[k] = cur
    return t

def turn_cov(x, tr, te, tol=0.02, ttol=0.05):
    span = float(np.ptp(x)) or 1.0
    d = branch_directions(x, tol * span)
    t = last_turn(x, d)
    ok = 0; tot = 0
    for k in (-1, 1):
        A = np.c_[x[tr & (d == k)], t[tr & (d == k)]]
        B = np.c_[x[te & (d == k)], t[te & (d == k)]]
        tot += len(B)
        if len(A) == 0 or len(B) == 0:
            continue
        # grid bucket lookup
        qa = np.floor(A / np.array([tol * span, ttol * span])).astype(int)
        S = set(map(tuple, qa))
        qb = np.floor(B / np.array([tol * span, ttol * span])).astype(int)
        for q in qb:
            if any((q[0] + i, q[1] + j) in S for i in (-1, 0, 1) for j in (-1, 0, 1)):
                ok += 1
    return ok / tot if tot else 1.0

rows = {}
for dd in sys.argv[1:]:
    for p in glob.glob(dd + "/s*.json"):
        for r in json.load(open(p)):
            rows[r["seed"]] = r
out = []
for s in sorted(rows):
    line = subprocess.check_output([sys.executable, "/work/main/.notes/session48/random_cells.py", str(s)], text=True).strip()
    minutes, cell = float(line.split("\t")[1]), json.loads(line.split("\t")[2])
    r = ip.make_record(s, minutes=minutes, **next(iter(cell.values())))
    h0 = r["heldout_start"]; x = np.asarray(r["sim"]["x_h"], float); n = x.size
    tr = np.arange(n) < h0; te = ~tr
    c = turn_cov(x, tr, te)
    rw = rows[s]
    out.append((c, rw["held"], s))
    print(f"{s} turncov {c:.3f} held {rw['held']:6.2f} train {rw['train']:.2f} {rw['cell']}", flush=True)
print()
for lo, hi in ((0.9, 1.01), (0.7, 0.9), (0.4, 0.7), (0.0, 0.4)):
    g = [o for o in out if lo <= o[0] < hi]
    if g:
        h = np.array([o[1] for o in g])
        print(f"turning-point coverage [{lo}, {hi}): {len(g)} cells, gm held {np.exp(np.mean(np.log(h))):.2f}, within 1.5x {int((h <= 1.5).sum())}, within 3x {int((h <= 3).sum())}")
