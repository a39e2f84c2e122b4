"""Stored 3-class fits (sessions 27-28): today's auto rule with and without the free Preisach cascade."""
import json, math, sys, collections
M = 2.0
gm = lambda x: math.exp(sum(math.log(max(a, 1e-9)) for a in x) / len(x))
def auto(v, classes):
    best = min(classes, key=lambda c: v[c]["val_rmse"]); d = v["cascade"]
    return "cascade" if best != "cascade" and d["val_rmse"] < M * v[best]["val_rmse"] and d["train_rmse"] <= v[best]["train_rmse"] else best
for path in sys.argv[1:]:
    recs = collections.defaultdict(dict)
    for line in open(path):
        r = json.loads(line); recs[(r["cell"], r["seed"])][r["cls"]] = r
    full = [v for v in recs.values() if {"cascade", "cascade-preisach", "cascade-preisach-gauss"} <= set(v)]
    for name, cl in (("with free", ("cascade", "cascade-preisach", "cascade-preisach-gauss")), ("without", ("cascade", "cascade-preisach-gauss"))):
        h = [v[auto(v, cl)]["held_x"] for v in full]
        print(f"{path.split('/')[-1]:40s} {name:10s} n={len(h)} gm {gm(h):.2f} <=1.5 {sum(x <= 1.5 for x in h)} <=3 {sum(x <= 3 for x in h)}")
