"""Default vs option rows of the random cells, per seed (session 48): python pair.py DEFAULT_DIR OTHER_DIR"""
import glob
import json
import sys

import numpy as np

a = {r["seed"]: r for p in glob.glob(sys.argv[1] + "/s*.json") for r in json.load(open(p))}
b = {r["seed"]: r for p in glob.glob(sys.argv[2] + "/s*.json") for r in json.load(open(p))}
ha, hb = [], []
for s in sorted(a):
    r = a[s]
    o = b.get(s)
    mc = " ".join(m.split(": ", 1)[-1] for m in r.get("memory_choice") or [])
    line = f"{s} {r['cell'][:44]:44s} {r['memory']:10s} def {r['train']:.2f}/{r['val']:.2f}/{r['held']:6.2f}"
    if o:
        line += f"  opt {o['train']:.2f}/{o['val']:.2f}/{o['held']:6.2f}  {o['chosen'] if o['chosen'] != r['chosen'] else ''}"
        ha.append(r["held"])
        hb.append(o["held"])
    print(line, mc)
ha, hb = np.array(ha), np.array(hb)
g = lambda h: float(np.exp(np.mean(np.log(h))))
print(f"paired {len(ha)}: gm {g(ha):.2f} -> {g(hb):.2f}; within 1.5x {int((ha <= 1.5).sum())} -> {int((hb <= 1.5).sum())}; "
      f"within 3x {int((ha <= 3).sum())} -> {int((hb <= 3).sum())}")
