"""Session 67: paired answers of the blind diagnosis, before/after, replaying the whole-record naming (`rename`) on the
stored rankings with the naming guard at 2x (session 66) or 5x (session 67).
python .notes/session67/paired.py NEWDIR BASEDIR [BASEDIR ...]
NEWDIR: runs with the lagged rate_dependence; BASEDIR: runs of the same records with the session-66 code."""
import glob, json, sys, tempfile, collections
sys.path.insert(0, "experiments")
import indep_effects as ie
import smafl_jax as sj
import smafl_jax.diagnosis._naming as N
from smafl_jax.identify._metrics import noise_floor


def rows(d):
    out = {}
    for f in sorted(glob.glob(f"{d}/*.json")):
        if not f.endswith(".partial.json"):
            for r in json.load(open(f))["rows"]:
                out[(r["truth"], r["case"]["requested_seed"])] = r
    return out


_sd = {}
def noise_sd(truth, seed):
    if (truth, seed) not in _sd:
        with tempfile.TemporaryDirectory() as tmp:
            path, _ = ie.write_effect_record(tmp, truth, seed)
            _sd[(truth, seed)] = noise_floor([sj.load_record(path)])["sd"]
    return _sd[(truth, seed)]


def answer(r, guard):
    nm = r.get("naming")
    if not nm or not nm.get("ranking"):
        return r["selected_new"], r["ambiguous_new"] or []
    N.WHOLE_BASE_MAX = guard
    held = {c["name"]: c["heldout_gain"] for c in r["candidates"] if c.get("heldout_gain") is not None}
    (s, a), _ = N.rename(dict(nm), nm["split_selected"], nm["split_ambiguous"], min_gain=0.05,
                         noise_sd=noise_sd(r["truth"], r["case"]["requested_seed"]), heldout_gain=held)
    return s, a


def ok(truth, s, a):
    return (not s) if truth == "none" else bool(s) and (truth in s or truth in a)


if __name__ == "__main__":
    new = rows(sys.argv[1])
    base = {}
    for d in sys.argv[2:]:
        base.update(rows(d))
    t = collections.Counter()
    for key in sorted(new):
        truth, seed = key
        cols = []
        for label, r, g in (("s66", base.get(key), 2.0), ("lag", new[key], 2.0), ("final", new[key], 5.0)):
            if r is None:
                cols.append(f"{label} {'(no run)':24s}")
                continue
            s, a = answer(r, g)
            k = ok(truth, s, a)
            t[f"{label} {'clean' if truth == 'none' else 'effect'} right"] += k
            t[f"{label} {'clean' if truth == 'none' else 'effect'} n"] += 1
            if truth != "none" and s and not k:
                t[f"{label} effect wrong"] += 1
            cols.append(f"{label} {'+'.join(s) or 'none':20s}{'ok' if k else '--'}")
        print(f"{truth:18s} {seed:5d}  " + "  ".join(cols))
    print(dict(sorted(t.items())))
