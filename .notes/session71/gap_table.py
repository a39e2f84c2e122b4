import sys
sys.path.insert(0, ".notes/session67")
from paired import rows, answer, ok
R = "experiments/results/"
TR = ["none", "resistance_tc", "asymmetric_cooling", "ambient_drift", "nonlinear_cooling", "rate_dependence", "creep", "delay", "output_lag"]
old = {}
for d in ("diagnose_independent_session66", "diagnose_independent_session66/seed13", "diagnose_independent_session67/new",
          "diagnose_independent_session67/seed14"):
    old.update(rows(R + d))
auto = {}
for d in ("diagnose_independent_session69/auto", "diagnose_independent_session70/auto"):
    auto.update(rows(R + d))
for (truth, seed), r in sorted(old.items(), key=lambda kv: kv[1]["base_heldout_over_noise"]/kv[1]["base_train_over_noise"]):
    s_ = seed - 1000 * TR.index(truth)
    if not (10 <= s_ <= 14 or (truth == "none" and 39 <= s_ <= 48)): continue
    m = (truth, seed) in auto
    rr = auto.get((truth, seed), r)
    s, a = answer(rr, 5.0)
    ratio = r["base_heldout_over_noise"]/r["base_train_over_noise"]
    ra = rr["base_heldout_over_noise"]/rr["base_train_over_noise"]
    print(f"{truth:18s} {seed:5d} time ratio {ratio:5.2f} held {r['base_heldout_over_noise']:5.2f} {'auto ratio %5.2f' % ra if m else '':16s} {'+'.join(s) or 'none':25s} {'ok' if ok(truth, s, a) else '--'}")
