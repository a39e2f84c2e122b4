"""Summary of base_fit_before_after.py rows (JSON list files): per-cell held-out / noise, gm, counts within 1.5x / 3x.

python .notes/session47/matrix_summary.py A.json [B.json ...]
"""
import json
import sys
from collections import defaultdict

import numpy as np

rows = [r for p in sys.argv[1:] for r in json.load(open(p))]
by = defaultdict(list)
print("| cell | seed | chosen | train | val | held-out | s |")
print("|---|---|---|---|---|---|---|")
for r in sorted(rows, key=lambda r: (r["cell"], r["seed"])):
    by[r["cell"]].append(r["held"])
    print(f"| {r['cell']} | {r['seed']} | {r['chosen']} | {r['train']:.2f} | {r['val']:.2f} | {r['held']:.2f} | {r['seconds']:.0f} |")
h = np.array([r["held"] for r in rows])
gm = lambda x: float(np.exp(np.mean(np.log(x))))
print()
for c, v in by.items():
    v = np.array(v)
    print(f"- {c}: gm {gm(v):.2f}x, within 1.5x {int(np.sum(v <= 1.5))}/{len(v)}, within 3x {int(np.sum(v <= 3))}/{len(v)}")
print(f"\nall {len(h)} records: gm {gm(h):.2f}x, median {np.median(h):.2f}x, within 1.5x {int(np.sum(h <= 1.5))}, "
      f"within 3x {int(np.sum(h <= 3))}, max {h.max():.1f}x; mean fit {np.mean([r['seconds'] for r in rows]):.0f} s")
