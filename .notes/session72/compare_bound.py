"""Session 72: runners-up refined only where the best start's simplex ends at a bound (`REFINED_STARTS = 3` with
`retry_if`) against the stored default answers (sessions 66-70, as `.notes/session70/tally_auto.py`).
python .notes/session72/compare_bound.py DIR [LOGDIR]   (LOGDIR: the runs' logs, to count the triggered candidate fits)"""
import glob, os, re, sys
sys.path.insert(0, ".notes/session67")
from paired import rows, answer, ok  # noqa: E402

R = "experiments/results/"
base = {}
for d in ("diagnose_independent_session66", "diagnose_independent_session66/seed13", "diagnose_independent_session67/new",
          "diagnose_independent_session67/seed14", "diagnose_independent_session69/auto", "diagnose_independent_session70/auto"):
    base.update(rows(R + d))  # later folders replace earlier runs of the same record (auto where it moved the split)
new = rows(sys.argv[1])
logs = sys.argv[2] if len(sys.argv) > 2 else None
tb = tn = n = 0
print("| truth | seed | default answer | bound-retry answer | candidate fits retried | seconds default -> new |")
print("|---|---|---|---|---|---|")
for k in sorted(new):
    r, o = new[k], base.get(k)
    sn, an = answer(r, 5.0)
    so, ao = answer(o, 5.0) if o else ([], [])
    kn, ko = ok(k[0], sn, an), ok(k[0], so, ao)
    tb += ko; tn += kn; n += 1
    s_ = k[1] - 1000 * ["none", "resistance_tc", "asymmetric_cooling", "ambient_drift", "nonlinear_cooling",
                        "rate_dependence", "creep", "delay", "output_lag"].index(k[0])
    retried = ""
    if logs:
        f = os.path.join(logs, f"{k[0]}_{s_}.log")
        if os.path.exists(f):
            retried = sorted({m for m in re.findall(r"fit ([a-z_+]+): .*simplex runs", open(f).read())})
            retried = ", ".join(retried) or "-"
    amb = lambda s, a: ("+".join(s) or "none") + (f" (ambiguous {'/'.join(a)})" if a else "")
    print(f"| {k[0]} | {k[1]} | {amb(so, ao)} {'ok' if ko else '--'} | {amb(sn, an)} {'ok' if kn else '--'} | {retried} | "
          f"{o['seconds'] if o else float('nan'):.0f} -> {r['seconds']:.0f} |")
print(f"\nright: default {tb}/{n}, bound-retry {tn}/{n}")
