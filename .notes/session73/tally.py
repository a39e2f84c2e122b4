"""Session 73: per-record answers over seeds 10-14 + clean 39-48 with the newest run of each record
(session 70 tally_auto's answer, replaced by runs under the bound rule: session 72 bound_retry, session 73 rows).
python .notes/session73/tally.py [EXTRA_DIR ...]"""
import collections, io, contextlib, sys
sys.path.insert(0, ".notes/session70")
sys.path.insert(0, ".notes/session67")
from paired import rows, answer, ok  # noqa: E402

with contextlib.redirect_stdout(io.StringIO()):
    import tally_auto as ta  # noqa: E402  (prints its own table on import)

R = "experiments/results/"
newer = {}
for d in [R + "diagnose_independent_session72/bound_retry"] + sys.argv[1:]:
    newer.update(rows(d))
t = collections.defaultdict(lambda: [0, 0, 0, 0])  # right, wrong, n, under rule
for (truth, seed), r in sorted(ta.old.items()):
    s_ = seed - 1000 * ta.TRUTHS.index(truth)
    if not (10 <= s_ <= 14 or (truth == "none" and 39 <= s_ <= 48)):
        continue
    if (truth, seed) in newer:
        s, a = answer(newer[(truth, seed)], 5.0)
        src = "rule"
    elif (truth, seed) in ta.auto:
        s, a = answer(ta.auto[(truth, seed)], 5.0)
        src = "auto"
    else:
        s, a = ta.floor.get((truth, seed)) or answer(r, 5.0)
        src = "time"
    k = ok(truth, s, a)
    v = t[truth]
    v[0] += k; v[1] += truth != "none" and bool(s) and not k; v[2] += 1; v[3] += src == "rule"
    amb = f" (ambiguous {'/'.join(a)})" if a else ""
    print(f"{truth:18s} {s_:3d} {src:5s} {('+'.join(s) or 'none') + amb:50s} {'ok' if k else '--'}")
print("| truth | records | under the bound rule | right | wrong |")
print("|---|---|---|---|---|")
for k in ta.TRUTHS:
    v = t[k]
    print(f"| {k} | {v[2]} | {v[3]} | {v[0]} | {v[1]} |")
eff = [v for k, v in t.items() if k != "none"]
print(f"effects {sum(v[0] for v in eff)}/{sum(v[2] for v in eff)} right, {sum(v[1] for v in eff)} wrong; "
      f"clean {t['none'][0]}/{t['none'][2]}")
