import collections, json, math, sys, glob
sys.path.insert(0, "experiments/results/class_choice_phase_session54")
from rules import auto, gm, ALL
NOW = ("cascade", "cascade-preisach-gauss", "cascade-phase")
recs = collections.defaultdict(dict)
for path in glob.glob("experiments/results/class_choice_phase_session54/*.jsonl"):
    for line in open(path):
        r = json.loads(line); recs[(path.split("/")[-1], r["cell"], r["seed"])][r["cls"]] = r
full = {k: v for k, v in recs.items() if set(v) >= set(NOW)}
def rule(v, trig, margin, use_cov=None):
    a = auto(v, NOW)
    if use_cov is not None and (v[a].get("coverage") or 1) >= use_cov: return a
    if v[a]["train_x"] <= trig: return a
    b = min(NOW, key=lambda c: v[c]["train_x"])
    return b if v[b]["train_x"] * margin < v[a]["train_x"] else a
for trig in (1.5, 2, 3, 5):
    for margin in (1.5, 2, 3):
        for cov in (None, 0.9):
            h = [v[rule(v, trig, margin, cov)]["held_x"] for v in full.values()]
            ch = [(k[1], k[2], auto(v, NOW), rule(v, trig, margin, cov), round(v[auto(v, NOW)]["held_x"],1), round(v[rule(v, trig, margin, cov)]["held_x"],1)) for k, v in full.items() if rule(v, trig, margin, cov) != auto(v, NOW)]
            print(trig, margin, cov, "gm", round(gm(h),3), "<=1.5", sum(x<=1.5 for x in h), "<=3", sum(x<=3 for x in h), "changed", len(ch), [c[4:] for c in ch])
h0=[v[auto(v, NOW)]["held_x"] for v in full.values()]; print("base gm", round(gm(h0),3), len(h0))
