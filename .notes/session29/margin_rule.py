"""Session 29: class-choice rules on the stored per-class fits (session 28 jsonl): keep the EUPI cascade unless another
class's validation RMSE is below m x the cascade's.  python margin_rule.py"""
import json, glob, math, collections, os
D = os.path.join(os.path.dirname(__file__), "../../experiments/results/class_choice_coverage_session28")
groups = {}
for f in sorted(glob.glob(D + "/*.jsonl")):
    recs = collections.defaultdict(dict)
    for line in open(f):
        r = json.loads(line)
        recs[(r["cell"], r["seed"])][r["cls"]] = r
    groups[os.path.basename(f)] = {k: v for k, v in recs.items() if len(v) == 3}
def rule_margin(m):
    def pick(c):
        base = c["cascade"]
        best = min(c.values(), key=lambda r: r["val_rmse"])
        return best if best["val_rmse"] < m * base["val_rmse"] else base
    return pick
def rule_margin_train(m, t):
    def pick(c):
        base = c["cascade"]
        ok = [r for r in c.values() if r["val_rmse"] < m * base["val_rmse"] and r["train_rmse"] < t * base["train_rmse"]]
        return min(ok, key=lambda r: r["val_rmse"]) if ok else base
    return pick
rules = {"validation": lambda c: min(c.values(), key=lambda r: r["val_rmse"]), "cascade": lambda c: c["cascade"],
         "oracle": lambda c: min(c.values(), key=lambda r: r["held_x"])}
for m in (0.95, 0.9, 0.8, 0.7, 0.5):
    rules[f"margin {m}"] = rule_margin(m)
for m in (1.0, 0.9, 0.8):
    for t in (1.5, 3.0):
        rules[f"margin {m} train<{t}"] = rule_margin_train(m, t)
def stats(vals):
    return math.exp(sum(math.log(v) for v in vals) / len(vals)), sum(v <= 1.5 for v in vals), sum(v <= 3 for v in vals)
print("rule".ljust(24), " | ".join(g[:22].ljust(22) for g in groups), "| all")
for name, pick in rules.items():
    row, allv = [], []
    for g, recs in groups.items():
        v = [pick(c)["held_x"] for c in recs.values()]
        allv += v
        row.append("%6.2f %2d %2d /%2d" % (*stats(v), len(v)))
    print(name.ljust(24), " | ".join(x.ljust(22) for x in row), "| %6.2f %2d %2d /%2d" % (*stats(allv), len(allv)))
