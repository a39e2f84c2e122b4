"""Compare the prescreen run (pA/pB) with the earlier rows of the same records: seeds 23-43 session-46 code + rule flips, 47/53 rule."""
import json, numpy as np
old = {}
for p in ("/tmp/s47/mA.json", "/tmp/s47/mB.json", "/tmp/s47/mNew.json"):
    for r in json.load(open(p)):
        old[(r["cell"], r["seed"])] = r
# the rule's flips (cascade kept): their held-out under the rule
rule_held = {("multisine, half-warm, 10 Hz", 23): 2.1649, ("multisine, half-warm, 10 Hz", 37): 1.1796, ("random_levels, cold, 20 Hz, length sensor", 37): 5.53}
new = [r for p in ("/tmp/s47/pA.json", "/tmp/s47/pB.json") for r in json.load(open(p))]
gm = lambda x: float(np.exp(np.mean(np.log(x))))
a, b = [], []
for r in new:
    k = (r["cell"], r["seed"]); o = old[k]
    before = rule_held.get(k, o["held"])
    a.append(before); b.append(r["held"])
    flag = "" if abs(before - r["held"]) < 1e-6 * max(1, before) else "  <-- changed"
    print(f"{k[0][:30]:30s} {k[1]:3d} rule-only {before:7.2f}  + prescreen {r['held']:7.2f} ({r['chosen']}, orient {r['fit_orientation']} sensor {r['sensor']}){flag}")
a, b = np.array(a), np.array(b)
print(f"{len(a)} records: gm {gm(a):.3f} -> {gm(b):.3f}; within 1.5x {int((a<=1.5).sum())} -> {int((b<=1.5).sum())}; within 3x {int((a<=3).sum())} -> {int((b<=3).sum())}; max {a.max():.1f} -> {b.max():.1f}")
