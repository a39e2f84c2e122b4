# run from .notes/session43
"""Old auto (three classes) vs new auto (+ the sparse EUPI grid) on the same 30 records, from one new-auto run: the old
rule's pick is the lowest validation RMSE among the old candidates (same deterministic fits); its held-out error is the
new run's when the pick is the same, the --model cascade run's when the old pick is the default cascade."""
import json

import numpy as np

a = {(r['cell'], r['seed']): r for r in map(json.loads, open('matrix_cascade_default_grid.jsonl'))}
rows = []
for r in map(json.loads, open('matrix_auto_new.jsonl')):
    c = r['candidates']
    old = min((k for k in c if 'sparse' not in k), key=lambda k: c[k])
    if old == r['chosen']:
        before = r['held']
    elif old == 'cascade':
        before = a[(r['cell'], r['seed'])]['held']
    else:
        before = json.load(open("s17_pwm_cold_preisach_gauss.json"))[0]["held"] if (r["cell"], r["seed"]) == ("PWM, cold, 25 Hz", 17) else np.nan
    rows.append((r['cell'], r['seed'], old, before, r['chosen'], r['held'], r['seconds']))
    print(f"| {r['cell']} | {r['seed']} | {old} | {before:.2f} | {r['chosen']} | {r['held']:.2f} |")
b = np.array([x[3] for x in rows]); n = np.array([x[5] for x in rows])
for lab, h in (('before', b), ('after', n)):
    print(f"{lab}: gm {np.exp(np.mean(np.log(h))):.2f}x, within 1.5x {(h <= 1.5).sum()}/30, within 3x {(h <= 3).sum()}/30, max {h.max():.1f}")
print('better by >10%:', int(np.sum(n < b / 1.1)), 'worse by >10%:', int(np.sum(n > 1.1 * b)), 'sparse kept:', sum('sparse' in x[4] for x in rows))
print('mean seconds per fit', np.mean([x[6] for x in rows]))
