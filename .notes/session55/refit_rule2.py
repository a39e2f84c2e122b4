import json, glob, collections, math, sys
sys.path.insert(0, "experiments/results/class_choice_phase_session54")
from rules import gm, MARGIN
recs = collections.defaultdict(dict)
for f in glob.glob("experiments/results/class_choice_coverage_session2*/*.jsonl"):
    for l in open(f):
        r = json.loads(l); recs[(f, r["cell"], r["seed"])][r["cls"]] = r
C = ("cascade", "cascade-preisach-gauss")
full = {k: v for k, v in recs.items() if set(v) >= set(C)}
def auto(v):
    best = min(C, key=lambda c: v[c]["val_rmse"]); d = v["cascade"]
    keep = d["val_rmse"] < MARGIN * v[best]["val_rmse"] and d["train_rmse"] <= v[best]["train_rmse"]
    return "cascade" if best != "cascade" and keep else best
def rule(v, trig=2, margin=2):
    a = auto(v)
    if v[a]["train_x"] <= trig: return a
    b = min(C, key=lambda c: v[c]["train_x"])
    return b if v[b]["train_x"] * margin < v[a]["train_x"] else a
h0 = [v[auto(v)]["held_x"] for v in full.values()]; h1 = [v[rule(v)]["held_x"] for v in full.values()]
print(len(full), "records; gm", round(gm(h0),3), "->", round(gm(h1),3))
for k, v in full.items():
    if rule(v) != auto(v): print(k[1], k[2], auto(v), "->", rule(v), round(v[auto(v)]["train_x"],2), round(v[rule(v)]["train_x"],2), "held", round(v[auto(v)]["held_x"],2), "->", round(v[rule(v)]["held_x"],2))
