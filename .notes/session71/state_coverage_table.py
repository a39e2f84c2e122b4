import sys
sys.path.insert(0, ".notes/session67")
from paired import rows, answer, ok
R = "experiments/results/"
TR = ["none", "resistance_tc", "asymmetric_cooling", "ambient_drift", "nonlinear_cooling", "rate_dependence", "creep", "delay", "output_lag"]
old = {}
for d in ("diagnose_independent_session66", "diagnose_independent_session66/seed13", "diagnose_independent_session67/new", "diagnose_independent_session67/seed14"):
    old.update(rows(R + d))
auto = {}
for d in ("diagnose_independent_session69/auto", "diagnose_independent_session70/auto"):
    auto.update(rows(R + d))
out = []
for (truth, seed), r in old.items():
    s_ = seed - 1000 * TR.index(truth)
    if not (10 <= s_ <= 14 or (truth == "none" and 39 <= s_ <= 48)): continue
    if (truth, seed) in auto: continue
    s, a = answer(r, 5.0)
    out.append((r["heldout_state_coverage"], r["heldout_coverage"], truth, seed, "+".join(s) or "none", ok(truth, s, a)))
for x in sorted(out): print(f"state {x[0]:.2f} input {x[1]:.2f} {x[2]:18s} {x[3]:5d} {x[4]:25s} {'ok' if x[5] else '--'}")
