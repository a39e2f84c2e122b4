"""Session 69 (python .notes/session69/compare.py DIR): paired answers, stored (session 66-67 runs, time block) vs new (split auto) for records rerun."""
import sys
sys.path.insert(0, ".notes/session67")
from paired import rows, answer, ok
R = "experiments/results/"
old = {}
for d in (R + "diagnose_independent_session66", R + "diagnose_independent_session66/seed13", R + "diagnose_independent_session67/new", R + "diagnose_independent_session67/seed14"):
    old.update(rows(d))
new = rows(sys.argv[1])
t = {"old": 0, "new": 0, "n": 0}
for k in sorted(new):
    r, o = new[k], old.get(k)
    sn, an = answer(r, 5.0)
    so, ao = answer(o, 5.0) if o else ([], [])
    kn, ko = ok(k[0], sn, an), ok(k[0], so, ao)
    t["old"] += ko; t["new"] += kn; t["n"] += 1
    sp = r.get("split_kind") or "?"
    print(f"{k[0]:18s} {k[1]:5d} cov {o['heldout_coverage'] if o else float('nan'):.2f} -> {r.get('heldout_coverage') or float('nan'):.2f} "
          f"base {o['base_heldout_over_noise'] if o else float('nan'):.2f}x -> {r['base_heldout_over_noise']:.2f}x  "
          f"old {'+'.join(so) or 'none':24s}{'ok' if ko else '--'}  new {'+'.join(sn) or 'none':24s}{'ok' if kn else '--'}  {r['seconds']:.0f}s")
print(t)
