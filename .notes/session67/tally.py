"""Session 67: per-effect tally over seeds 10-14 with the final rule (guard 5x), newest run of each record first.
python .notes/session67/tally.py   (at-floor records of seeds 10-11: the whole_only rankings, `floor_replay.py`)"""
import collections, glob, json, re, sys
sys.path.insert(0, ".notes/session67")
from paired import rows, answer, ok  # noqa: E402  (paired.py runs its table at import; see below)
from smafl_jax.diagnosis import rename  # noqa: E402

R = "experiments/results/"
recs = {}
for d in (R + "diagnose_independent_session66", R + "diagnose_independent_session66/seed13", R + "diagnose_independent_session67/new",
          R + "diagnose_independent_session67/seed14"):
    recs.update(rows(d))  # later folders replace earlier runs of the same record
floor = {}
for f in glob.glob(R + "diagnose_independent_session66/whole_only/*.txt"):
    txt = open(f).read().splitlines()
    if len(txt) < 3:
        continue
    truth, seed = txt[0].split()[0], int(txt[0].split()[1])
    wb = float(re.search(r"whole base ([\d.]+)x", txt[0]).group(1))
    rk = [(x.rsplit(" ", 1)[0], float(x.rsplit(" ", 1)[1])) for x in txt[1][len("ranked: "):].split(", ")]
    r = recs[(truth, seed)]
    held = {c["name"]: c["heldout_gain"] for c in r["candidates"] if c.get("heldout_gain") is not None}
    doc = {"base_rmse": wb, "ranking": [{"name": n, "gain": g, "rmse": wb * (1 - g)} for n, g in rk]}
    floor[(truth, seed)] = rename(doc, [], [], min_gain=0.05, noise_sd=1.0, heldout_gain=held)[0]
t = collections.defaultdict(lambda: [0, 0, 0])
for (truth, seed), r in sorted(recs.items()):
    s_ = seed - 1000 * ["none", "resistance_tc", "asymmetric_cooling", "ambient_drift", "nonlinear_cooling",
                        "rate_dependence", "creep", "delay", "output_lag"].index(truth)
    if not (10 <= s_ <= 14 or (truth == "none" and 39 <= s_ <= 48)):
        continue
    s, a = floor.get((truth, seed)) or answer(r, 5.0)
    k = ok(truth, s, a)
    t[truth][0] += k; t[truth][1] += 1; t[truth][2] += (truth != "none" and bool(s) and not k)
    print(f"{truth:18s} {seed:5d} {'+'.join(s) or 'none':30s} {'ok' if k else '--'}")
print({k: f"{v[0]}/{v[1]} right, {v[2]} wrong" for k, v in sorted(t.items())})
eff = [v for k, v in t.items() if k != "none"]
print("effects", sum(v[0] for v in eff), "/", sum(v[1] for v in eff), "right,", sum(v[2] for v in eff), "wrong; clean", t["none"][0], "/", t["none"][1])
