"""Replay: the EUPI cascade (the paper's class) kept unless another class's validation RMSE is below its own / (1 + m);
with TRAIN=1 in the environment also only when the cascade's split-training RMSE is not above that class's (the rule
session 47 shipped with m = 1, i.e. a factor 2).

Rows: experiments/class_choice_coverage.py output (every class fitted on each record, held-out of every class stored).
python .notes/session47/margin_rule.py FILE.jsonl ...   (each file one group)
"""
import json
import os
import sys
from collections import defaultdict

import numpy as np

MARGINS = tuple(float(x) for x in os.environ.get("MARGINS", "0,0.1,0.2,0.3,0.5,1,1e9").split(","))
gm = lambda x: float(np.exp(np.mean(np.log(x))))
allrows = defaultdict(list)
for path in sys.argv[1:]:
    recs = defaultdict(dict)
    for line in open(path):
        r = json.loads(line)
        recs[(r["cell"], r["seed"])][r["cls"]] = r
    out = {m: [] for m in MARGINS}
    oracle = []
    for key, by in recs.items():
        if "cascade" not in by or len(by) < 3:
            continue
        oracle.append(min(v["held_x"] for v in by.values()))
        for m in MARGINS:
            best = min(by, key=lambda c: by[c]["val_rmse"])
            pick = best if by[best]["val_rmse"] * (1 + m) < by["cascade"]["val_rmse"] else "cascade"
            if os.environ.get("TRAIN") == "1" and by["cascade"]["train_rmse"] > by[best]["train_rmse"]:
                pick = best
            out[m].append(by[pick]["held_x"])
    name = path.split("/")[-1]
    print(f"{name} ({len(oracle)} records; oracle gm {gm(oracle):.2f})")
    for m in MARGINS:
        h = np.array(out[m])
        allrows[m] += list(h)
        lab = "always cascade" if m > 1e6 else f"m = {m:g}"
        print(f"   {lab:15s} gm {gm(h):6.2f}  within 1.5x {int(np.sum(h <= 1.5)):2d}  within 3x {int(np.sum(h <= 3)):2d}")
print("all")
for m in MARGINS:
    h = np.array(allrows[m])
    lab = "always cascade" if m > 1e6 else f"m = {m:g}"
    print(f"   {lab:15s} gm {gm(h):6.2f}  within 1.5x {int(np.sum(h <= 1.5)):2d}  within 3x {int(np.sum(h <= 3)):2d}  ({len(h)})")
