"""Session 66: replay 'split gates decide whether, whole-record ranking decides which' on stored records.
python .notes/session66/combo.py ALLDIR DIAGDIR [DIAGDIR ...]"""
import glob, json, os, re, sys
from smafl_jax.effects import EFFECTS
alldir, dirs = sys.argv[1], sys.argv[2:]
DETECT = float(os.environ.get("DETECT", "0"))  # > 0: the whole record also detects when the gates say none
diag = {}
for d in dirs:
    for f in sorted(glob.glob(f"{d}/*.json")):
        if f.endswith(".partial.json"):
            continue
        for r in json.load(open(f))["rows"]:
            diag[(r["truth"], r["case"]["requested_seed"])] = r
def look(a, b):
    return a in EFFECTS and b in EFFECTS and bool(set(EFFECTS[a].lookalikes) & set(EFFECTS[b].lookalikes))
tot = dict(c_right=0, c_wrong=0, w_right=0, w_wrong=0, n=0, clean=0, c_clean=0, w_clean=0)
for f in sorted(glob.glob(f"{alldir}/*.all.txt")):
    txt = open(f).read().splitlines()
    head = txt[0].split()
    truth, seed = head[0], int(head[1].lstrip("s"))
    rk = [(x.rsplit(" ", 1)[0], float(x.rsplit(" ", 1)[1])) for x in txt[-1][len("ranked: "):].split(", ")]
    r = diag.get((truth, seed))
    if r is None:
        print("no diag", truth, seed); continue
    sel, amb = r["selected_new"], r["ambiguous_new"] or []
    first = rk[0][0]
    from smafl_jax.diagnosis import whole_record_name
    nm, namb = whole_record_name({"ranking": [{"name": n, "gain": g, "rmse": 1 - g} for n, g in rk]}, 0.05)
    combo = [nm] if sel and nm else []
    combo_amb = namb if sel else []
    wb = float(re.search(r"whole-record ([\d.]+)x", txt[0]).group(1))
    if DETECT and not sel and wb <= 2.0:
        d, damb = whole_record_name({"ranking": [{"name": n, "gain": g, "rmse": 1 - g} for n, g in rk]}, DETECT)
        combo, combo_amb = ([d], damb) if d else ([], [])
    lead = wb * (1 - rk[0][1]) if os.environ.get("LEAD") else wb
    if lead > float(os.environ.get("GUARD", "2.0")):  # WHOLE_BASE_MAX (measured noise here, the diagnosis uses its estimate): the gates' choice stands
        combo, combo_amb = list(sel), list(amb)
    def ok(s, a=()):
        if truth == "none":
            return not s
        return bool(s) and (truth in s or truth in a)
    cok, wok = ok(sel, amb), ok(combo, combo_amb)
    print(f"{truth:20s} {seed:5d} committed {'+'.join(sel) or 'none':30s} {'ok' if cok else '--'}  combo {'+'.join(combo) or 'none':18s} {','.join(combo_amb):28s} {'ok' if wok else '--'}  (first {first} {rk[0][1]:+.3f})")
    if truth == "none":
        tot["clean"] += 1; tot["c_clean"] += cok; tot["w_clean"] += wok
    else:
        tot["n"] += 1; tot["c_right"] += cok; tot["w_right"] += wok
        tot["c_wrong"] += bool(sel) and not cok; tot["w_wrong"] += bool(combo) and not wok
print(tot)
