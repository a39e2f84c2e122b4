# python .notes/session44/varpro_vs_lm.py AFTER.jsonl [S43_DIR]: issue 18's 30-record matrix, the default fit with the LM
# refinement (session 43's runs, the old three-class auto pick rebuilt as .notes/session43/before_after.py does) against
# a run with another setting (e.g. SMAFL_FIT_OPTS='{"solver": "varpro"}').
import json
import sys

import numpy as np

after_path = sys.argv[1]
s43 = sys.argv[2] if len(sys.argv) > 2 else ".notes/session43"
a = {(r["cell"], r["seed"]): r for r in map(json.loads, open(f"{s43}/matrix_cascade_default_grid.jsonl"))}
pg = json.load(open(f"{s43}/s17_pwm_cold_preisach_gauss.json"))[0]["held"]
before = {}
for r in map(json.loads, open(f"{s43}/matrix_auto_new.jsonl")):
    c = r["candidates"]
    old = min((k for k in c if "sparse" not in k), key=lambda k: c[k])
    if old == r["chosen"]:
        h = r["held"]
    elif old == "cascade":
        h = a[(r["cell"], r["seed"])]["held"]
    else:
        h = pg if (r["cell"], r["seed"]) == ("PWM, cold, 25 Hz", 17) else np.nan
    before[(r["cell"], r["seed"])] = (old, h, r["seconds"])
rows = []
for line in open(after_path):
    if not line.startswith("{"):
        continue
    r = json.loads(line)
    old, b, sb = before[(r["cell"], r["seed"])]
    rows.append((b, r["held"]))
    print(f"| {r['cell']} | {r['seed']} | {old} | {b:.2f} | {r['chosen']} | {r['train']:.2f} | {r['held']:.2f} | {r['seconds']:.0f} |")
b = np.array([x[0] for x in rows])
n = np.array([x[1] for x in rows])
for lab, h in (("before", b), ("after", n)):
    print(f"{lab}: gm {np.exp(np.mean(np.log(h))):.2f}x, within 1.5x {(h <= 1.5).sum()}/{len(h)}, within 3x {(h <= 3).sum()}/{len(h)}, max {h.max():.1f}")
print("better by >10%:", int(np.sum(n < b / 1.1)), "worse by >10%:", int(np.sum(n > 1.1 * b)))
