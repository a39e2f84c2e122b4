"""Class-choice rules on per-class fits (experiments/class_choice_coverage.py rows with cascade-phase)."""
import json, math, sys, collections
ALL = ("cascade", "cascade-preisach", "cascade-preisach-gauss", "cascade-phase")
M = 2.0
recs = collections.defaultdict(dict)
for path in sys.argv[1:]:
    for line in open(path):
        r = json.loads(line); recs[(path.split('/')[-1][:2], r["cell"], r["seed"])][r["cls"]] = r
full = {k: v for k, v in recs.items() if set(v) >= set(ALL)}
gm = lambda x: math.exp(sum(math.log(max(a, 1e-9)) for a in x) / len(x))
def auto(v, classes):  # today's fit_record rule: lowest validation, the default kept within 2x if it trains no worse
    best = min(classes, key=lambda c: v[c]["val_rmse"]); d = v["cascade"]
    return "cascade" if best != "cascade" and d["val_rmse"] < M * v[best]["val_rmse"] and d["train_rmse"] <= v[best]["train_rmse"] else best
def combined(v, classes):
    return min(classes, key=lambda c: v[c]["val_rmse"] ** 2 + v[c]["train_rmse"] ** 2)
def auto_combined(v, classes):
    best = combined(v, classes); d = v["cascade"]
    return "cascade" if best != "cascade" and d["val_rmse"] < M * v[best]["val_rmse"] and d["train_rmse"] <= v[best]["train_rmse"] else best
def auto_trainfloor(v, classes, f=2.0):
    # classes whose training RMSE is > f x the best training RMSE (and > 2x noise) are not credible; auto among the rest
    tb = min(v[c]["train_rmse"] for c in classes)
    ok = [c for c in classes if v[c]["train_rmse"] <= max(f * tb, 2.0 * v[c]["noise_sd"])]
    return auto(v, ok if "cascade" in ok else ok) if "cascade" in ok else min(ok, key=lambda c: v[c]["val_rmse"])
rules = {
    "auto, 3 classes (before)": lambda v: auto(v, ALL[:3]),
    "auto, 4 classes": lambda v: auto(v, ALL),
    "auto on val^2+train^2, 4": lambda v: auto_combined(v, ALL),
    "auto among credible trainers (<=2x best train or 2x noise), 4": lambda v: auto_trainfloor(v, ALL),
    "oracle 3": lambda v: min(ALL[:3], key=lambda c: v[c]["held_x"]),
    "oracle 4": lambda v: min(ALL, key=lambda c: v[c]["held_x"]),
}
groups = sorted(set(k[0] for k in full))
for g in groups + ["all"]:
    sel = {k: v for k, v in full.items() if g == "all" or k[0] == g}
    if not sel: continue
    print(f"\n## {g}: {len(sel)} records\n| rule | gm | <=1.5x | <=3x | picks phase |\n|---|---|---|---|---|")
    for name, rule in rules.items():
        picks = [rule(v) for v in sel.values()]
        h = [v[c]["held_x"] for v, c in zip(sel.values(), picks)]
        print(f"| {name} | {gm(h):.2f} | {sum(x <= 1.5 for x in h)} | {sum(x <= 3 for x in h)} | {sum(c == 'cascade-phase' for c in picks)} |")
if "-v" in sys.argv[0:0] or True:
    print("\n| record | " + " | ".join(c.replace('cascade', 'c') for c in ALL) + " | auto3 | auto4 |")
    for k, v in sorted(full.items()):
        sd = v["cascade"]["noise_sd"]
        cells = " | ".join(f"{v[c]['train_rmse']/sd:.1f}/{v[c]['val_rmse']/sd:.1f}/{v[c]['held_x']:.1f}" for c in ALL)
        print(f"| {k[0]} {k[1]} s{k[2]} | {cells} | {auto(v, ALL[:3])} | {auto(v, ALL)} |")
print("\n## without the free Preisach cascade")
for g in groups + ["all"]:
    sel = {k: v for k, v in full.items() if g == "all" or k[0] == g}
    for name, cl in (("auto 4", ALL), ("auto 3 (no free preisach)", ("cascade", "cascade-preisach-gauss", "cascade-phase")), ("auto 3 (no gauss)", ("cascade", "cascade-preisach", "cascade-phase"))):
        h = [v[auto(v, cl)]["held_x"] for v in sel.values()]
        print(f"{g} {name}: gm {gm(h):.2f} <=1.5 {sum(x <= 1.5 for x in h)} <=3 {sum(x <= 3 for x in h)}")
