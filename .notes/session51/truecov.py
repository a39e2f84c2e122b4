"""Coverage of the plant's TRUE hysteresis input (held-out vs training part) per random cell, beside the default fit's
held-out error from the stored rows: are the misses extrapolations to untrained states of the plant?

Two measures: value + branch direction (`smafl_jax.data.split.branch_coverage`, 2 % of the span) and value + direction +
last turning point (5 % of the span).

    python .notes/session51/truecov.py ROWS_DIR [ROWS_DIR ...]
"""
import glob
import json
import subprocess
import sys

sys.path.insert(0, "/work/main/tests")
import numpy as np

import indep_plant as ip
from smafl_jax.data.split import branch_coverage, branch_directions


def last_turn(x, d):
    t = np.empty_like(x)
    cur, prev = x[0], 0
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
    cell = np.array([tol * span, ttol * span])
    ok = tot = 0
    for k in (-1, 1):
        a, b = np.c_[x[tr & (d == k)], t[tr & (d == k)]], np.c_[x[te & (d == k)], t[te & (d == k)]]
        tot += len(b)
        if len(a) and len(b):
            seen = set(map(tuple, np.floor(a / cell).astype(int)))
            ok += sum(any((q[0] + i, q[1] + j) in seen for i in (-1, 0, 1) for j in (-1, 0, 1)) for q in np.floor(b / cell).astype(int))
    return ok / tot if tot else 1.0


def groups(out, i, edges, label):
    for lo, hi in edges:
        h = np.array([o["held"] for o in out if lo <= o[i] < hi])
        if h.size:
            print(f"{label} [{lo}, {hi}): {h.size} cells, gm held {np.exp(np.mean(np.log(h))):.2f}, within 1.5x "
                  f"{int((h <= 1.5).sum())}, within 3x {int((h <= 3).sum())}")


rows = {r["seed"]: r for d in sys.argv[1:] for p in glob.glob(d + "/s*.json") for r in json.load(open(p))}
out = []
for s in sorted(rows):
    line = subprocess.check_output([sys.executable, "/work/main/.notes/session48/random_cells.py", str(s)], text=True).strip()
    minutes, cell = float(line.split("\t")[1]), json.loads(line.split("\t")[2])
    r = ip.make_record(s, minutes=minutes, **next(iter(cell.values())))
    x = np.asarray(r["sim"]["x_h"], float)
    tr = np.arange(x.size) < r["heldout_start"]
    te = ~tr
    rw = rows[s]
    o = {"cov": branch_coverage(x, tr, te)["covered_fraction"], "turn": turn_cov(x, tr, te), "held": rw["held"]}
    out.append(o)
    print(f"{s} cov {o['cov']:.3f} turncov {o['turn']:.3f} held {rw['held']:6.2f} train {rw['train']:.2f} {rw['cell']}", flush=True)
print()
groups(out, "cov", ((0.95, 1.01), (0.9, 0.95), (0.7, 0.9), (0.0, 0.7)), "coverage")
groups(out, "turn", ((0.9, 1.01), (0.7, 0.9), (0.4, 0.7), (0.0, 0.4)), "turning-point coverage")
