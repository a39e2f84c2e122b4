"""Session 70: per-effect tally over seeds 10-14 + clean 39-48, time block (sessions 66-67 runs, as
.notes/session67/tally.py) against `--split auto` (the records auto moves rerun in sessions 69-70; the others are
unchanged by auto: their time block covers >= 90 % and auto keeps it).
python .notes/session70/tally_auto.py"""
import collections, glob, re, sys
sys.path.insert(0, ".notes/session67")
from paired import rows, answer, ok  # noqa: E402
from smafl_jax.diagnosis import rename  # noqa: E402

R = "experiments/results/"
TRUTHS = ["none", "resistance_tc", "asymmetric_cooling", "ambient_drift", "nonlinear_cooling", "rate_dependence",
          "creep", "delay", "output_lag"]
old = {}
for d in ("diagnose_independent_session66", "diagnose_independent_session66/seed13", "diagnose_independent_session67/new",
          "diagnose_independent_session67/seed14"):
    old.update(rows(R + d))  # later folders replace earlier runs of the same record
auto = {}
for d in ("diagnose_independent_session69/auto", "diagnose_independent_session70/auto"):
    auto.update(rows(R + d))
floor = {}  # seeds 10-11 at the floor: the whole-record rankings replayed (session 66, `floor_replay.py`)
for f in glob.glob(R + "diagnose_independent_session66/whole_only/*.txt"):
    txt = open(f).read().splitlines()
    if len(txt) < 3:
        continue
    truth, seed = txt[0].split()[0], int(txt[0].split()[1])
    wb = float(re.search(r"whole base ([\d.]+)x", txt[0]).group(1))
    rk = [(x.rsplit(" ", 1)[0], float(x.rsplit(" ", 1)[1])) for x in txt[1][len("ranked: "):].split(", ")]
    r = old[(truth, seed)]
    held = {c["name"]: c["heldout_gain"] for c in r["candidates"] if c.get("heldout_gain") is not None}
    doc = {"base_rmse": wb, "ranking": [{"name": n, "gain": g, "rmse": wb * (1 - g)} for n, g in rk]}
    floor[(truth, seed)] = rename(doc, [], [], min_gain=0.05, noise_sd=1.0, heldout_gain=held)[0]
t = collections.defaultdict(lambda: [0, 0, 0, 0, 0, 0])  # time right, wrong; auto right, wrong; n; moved
for (truth, seed), r in sorted(old.items()):
    s_ = seed - 1000 * TRUTHS.index(truth)
    if not (10 <= s_ <= 14 or (truth == "none" and 39 <= s_ <= 48)):
        continue
    so, ao = floor.get((truth, seed)) or answer(r, 5.0)
    moved = (truth, seed) in auto
    sn, an = answer(auto[(truth, seed)], 5.0) if moved else (so, ao)
    ko, kn = ok(truth, so, ao), ok(truth, sn, an)
    v = t[truth]
    v[0] += ko; v[1] += truth != "none" and bool(so) and not ko
    v[2] += kn; v[3] += truth != "none" and bool(sn) and not kn
    v[4] += 1; v[5] += moved
    if moved:
        print(f"{truth:18s} {seed:5d} time {'+'.join(so) or 'none':28s}{'ok' if ko else '--'}  auto {'+'.join(sn) or 'none':28s}{'ok' if kn else '--'}")
print("| truth | records | moved by auto | time: right / wrong | auto: right / wrong |")
print("|---|---|---|---|---|")
for k in TRUTHS:
    v = t[k]
    print(f"| {k} | {v[4]} | {v[5]} | {v[0]} / {v[1]} | {v[2]} / {v[3]} |")
eff = [v for k, v in t.items() if k != "none"]
print(f"effects: time {sum(v[0] for v in eff)}/{sum(v[4] for v in eff)} right, {sum(v[1] for v in eff)} wrong; "
      f"auto {sum(v[2] for v in eff)}/{sum(v[4] for v in eff)} right, {sum(v[3] for v in eff)} wrong; "
      f"clean time {t['none'][0]}/{t['none'][4]}, auto {t['none'][2]}/{t['none'][4]}")
