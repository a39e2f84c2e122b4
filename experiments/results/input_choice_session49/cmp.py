"""Held-out error per random cell, base rows vs new rows (session 49).

python experiments/results/input_choice_session49/cmp.py BASE_DIR NEW_DIR [OVERRIDE_DIR]  (OVERRIDE_DIR rows replace NEW_DIR's)
"""

import glob
import json
import sys

import numpy as np


def load(d):
    return {r["seed"]: r for p in glob.glob(d + "/s*.json") for r in json.load(open(p))}


def gm(h):
    return float(np.exp(np.mean(np.log(h))))


a = load(sys.argv[1])
b = load(sys.argv[2])
if len(sys.argv) > 3:
    b.update(load(sys.argv[3]))
ha, hb = [], []
for s in sorted(set(a) & set(b)):
    r, o = a[s], b[s]
    ha.append(r["held"])
    hb.append(o["held"])
    flag = "" if abs(np.log(o["held"] / r["held"])) < 0.02 else ("BETTER" if o["held"] < r["held"] else "WORSE")
    ch = "" if o["chosen"] == r["chosen"] else f"{r['chosen']}->{o['chosen']}"
    picked = [m.split("->")[-1].split(";")[0].strip() for m in o.get("memory_choice") or [] if "->" in m]
    print(
        f"{s} {r['cell'][:42]:42s} train {r['train']:.2f}->{o['train']:.2f} held {r['held']:6.2f} -> {o['held']:6.2f} "
        f"{flag:6s} {ch} {picked[-1] if picked else ''}"
    )
ha, hb = np.array(ha), np.array(hb)
print(
    f"paired {len(ha)}: gm {gm(ha):.2f} -> {gm(hb):.2f}; median {np.median(ha):.2f} -> {np.median(hb):.2f}; "
    f"within 1.5x {int((ha <= 1.5).sum())} -> {int((hb <= 1.5).sum())}; within 3x {int((ha <= 3).sum())} -> {int((hb <= 3).sum())}; "
    f"max {ha.max():.1f} -> {hb.max():.1f}"
)
