"""Session 73: records whose whole-record name holds out worse than the base on the split (newest run of each record,
seeds 10-14 + clean 39-48, as tally.py), and what two alternatives would answer: the gates' own choice, or nothing.
python .notes/session73/contradicted.py [EXTRA_DIR ...]"""
import io, contextlib, sys
sys.path.insert(0, ".notes/session70")
sys.path.insert(0, ".notes/session67")
from paired import rows, answer, ok  # noqa: E402

with contextlib.redirect_stdout(io.StringIO()):
    import tally_auto as ta  # noqa: E402

R = "experiments/results/"
newer = {}
for d in [R + "diagnose_independent_session72/bound_retry"] + sys.argv[1:]:
    newer.update(rows(d))
for (truth, seed), r in sorted(ta.old.items()):
    s_ = seed - 1000 * ta.TRUTHS.index(truth)
    if not (10 <= s_ <= 14 or (truth == "none" and 39 <= s_ <= 48)):
        continue
    r = newer.get((truth, seed)) or ta.auto.get((truth, seed)) or r
    nm = r.get("naming") or {}
    s, a = answer(r, 5.0)
    if not s or not nm.get("ranking"):
        continue
    held = {c["name"]: c.get("heldout_gain") for c in r["candidates"]}
    g = held.get(s[0])
    if g is None or g >= 0:
        continue
    gates = nm.get("split_selected") or []
    print(f"{truth:18s} {s_:3d} named {'+'.join(s):25s} split gain {g:+.3f} {'ok' if ok(truth, s, a) else '--'} | "
          f"gates' {'+'.join(gates) or 'none':20s} {'ok' if ok(truth, gates, []) else '--'} | nothing {'ok' if truth == 'none' else '--'}")
