"""Matrix rows of the margin code against the stored session-47 rows (same records), session 48."""
import glob
import json
import sys

import numpy as np

old = {(r["seed"], r["cell"]): r for p in glob.glob("experiments/results/class_rule_session47/matrix_fresh_*_rule_prescreen.json")
       for r in json.load(open(p))}
new = {(r["seed"], r["cell"]): r for p in sys.argv[1:] for r in json.load(open(p))}
a, b = [], []
for k in sorted(new):
    if k not in old:
        continue
    o, n = old[k], new[k]
    a.append(o["held"])
    b.append(n["held"])
    flag = "CHANGED" if abs(o["held"] - n["held"]) > 1e-3 * o["held"] else ""
    print(f"{k[0]} {k[1][:40]:40s} {o['held']:7.2f} -> {n['held']:7.2f} {flag}")
a, b = np.array(a), np.array(b)
g = lambda h: float(np.exp(np.mean(np.log(h))))
print(f"{len(a)} records: gm {g(a):.2f} -> {g(b):.2f}; within 1.5x {(a <= 1.5).sum()} -> {(b <= 1.5).sum()}; within 3x {(a <= 3).sum()} -> {(b <= 3).sum()}")
