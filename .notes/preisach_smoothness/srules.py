import json, math, sys
gm = lambda v: math.exp(sum(map(math.log, v)) / len(v))
rows = [json.loads(l) for l in open(sys.argv[1])]
L = ["0.0", "1e-07", "1e-06", "1e-05", "0.0001", "0.001", "0.01"]
def r_total(r):
    return min(L, key=lambda l: sum(r["folds"][l]))
def r_majority(r, need=3):
    base = r["folds"]["0.0"]
    ok = [l for l in L[1:] if sum(a < b for a, b in zip(r["folds"][l], base)) >= need]
    return min(ok, key=lambda l: sum(r["folds"][l])) if ok and min(sum(r["folds"][l]) for l in ok) < sum(base) else "0.0"
def r_median(r):
    import statistics
    base = r["folds"]["0.0"]
    ratio = {l: statistics.median([a / b for a, b in zip(r["folds"][l], base)]) for l in L}
    return min(L, key=lambda l: ratio[l])
def r_weakest_within(r, tol=1.1):  # the weakest strength whose total is within tol of the best: one-SE-like but toward weak
    best = min(sum(r["folds"][l]) for l in L)
    return next(l for l in L if sum(r["folds"][l]) <= tol * best)
def r_max(r):  # minimise the worst fold ratio
    base = r["folds"]["0.0"]
    return min(L, key=lambda l: max(a / b for a, b in zip(r["folds"][l], base)))
for lab, rule in (("total", r_total), ("majority3", r_majority), ("all4", lambda r: r_majority(r, 4)), ("median-ratio", r_median), ("weakest-within1.1", r_weakest_within), ("minimax-ratio", r_max)):
    s = [r["held"]["0.0"] for r in rows]; c = [r["held"][rule(r)] for r in rows]
    print(f"{lab:18s} gm {gm(s):.2f} -> {gm(c):.2f} better>10% {sum(b < a/1.1 for a,b in zip(s,c))} worse>10% {sum(b > 1.1*a for a,b in zip(s,c))} worst ratio {max(b/a for a,b in zip(s,c)):.2f}")
