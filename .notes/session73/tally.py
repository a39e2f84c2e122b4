"""Session 73: per-record answers over seeds 10-14 + clean 39-48 with the newest run of each record (common.newest).
python .notes/session73/tally.py [EXTRA_DIR ...]"""
import collections, sys
sys.path.insert(0, ".notes/session73")
from common import TRUTHS, newest, ok  # noqa: E402

t = collections.defaultdict(lambda: [0, 0, 0, 0])  # right, wrong, n, under rule
for truth, s_, r, (s, a), src in newest(sys.argv[1:]):
    k = ok(truth, s, a)
    v = t[truth]
    v[0] += k; v[1] += truth != "none" and bool(s) and not k; v[2] += 1; v[3] += src == "rule"
    amb = f" (ambiguous {'/'.join(a)})" if a else ""
    print(f"{truth:18s} {s_:3d} {src:5s} {('+'.join(s) or 'none') + amb:50s} {'ok' if k else '--'}")
print("| truth | records | under the bound rule | right | wrong |")
print("|---|---|---|---|---|")
for k in TRUTHS:
    v = t[k]
    print(f"| {k} | {v[2]} | {v[3]} | {v[0]} | {v[1]} |")
eff = [v for k, v in t.items() if k != "none"]
print(f"effects {sum(v[0] for v in eff)}/{sum(v[2] for v in eff)} right, {sum(v[1] for v in eff)} wrong; "
      f"clean {t['none'][0]}/{t['none'][2]}")
