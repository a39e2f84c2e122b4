import json, sys, numpy as np
old = {json.loads(l)["record"]: json.loads(l) for l in open("/work/main/experiments/results/plant_c_session45_weak_columns.jsonl")}
new = {}
for p in sys.argv[1:]:
    for l in open(p):
        r = json.loads(l); new[r["record"]] = r
for k in sorted(new):
    o, r = old.get(k, {}), new[k]
    nr = {kk: round(v, 2) for kk, v in r.items() if kk.startswith("new_") and isinstance(v, float)}
    no = {kk: round(v, 2) for kk, v in o.items() if kk.startswith("new_") and isinstance(v, float)}
    print(f"{k} train {o.get('train', float('nan')):.2f} -> {r['train']:.2f} held {o.get('held', float('nan')):.2f} -> {r['held']:.2f} {o.get('chosen')} -> {r.get('chosen')} {r.get('fit_seconds', 0):.0f}s  new runs {no} -> {nr}")
