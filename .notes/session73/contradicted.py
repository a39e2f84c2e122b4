"""Session 73: records whose whole-record name holds out worse than the base on the split (newest run of each record,
common.newest), and what two alternatives would answer: the gates' own choice, or nothing.
python .notes/session73/contradicted.py [EXTRA_DIR ...]"""
import sys
sys.path.insert(0, ".notes/session73")
from common import newest, ok  # noqa: E402

for truth, s_, r, (s, a), _ in newest(sys.argv[1:]):
    nm = r.get("naming") or {}
    if not s or not nm.get("ranking"):
        continue
    g = {c["name"]: c.get("heldout_gain") for c in r["candidates"]}.get(s[0])
    if g is None or g >= 0:
        continue
    gates = nm.get("split_selected") or []
    print(f"{truth:18s} {s_:3d} named {'+'.join(s):25s} split gain {g:+.3f} {'ok' if ok(truth, s, a) else '--'} | "
          f"gates' {'+'.join(gates) or 'none':20s} {'ok' if ok(truth, gates, []) else '--'} | nothing {'ok' if truth == 'none' else '--'}")
