"""Replay: whole-record ranking also DETECTS (gates say none): named when the whole-record base <= 2x the noise
and the first gains >= T.  python detect_replay.py ALLDIR T"""
import glob, re, sys
from smafl_jax.diagnosis import whole_record_name
alldir, T = sys.argv[1], float(sys.argv[2])
tot = {}
for f in sorted(glob.glob(f"{alldir}/*.all.txt")):
    txt = open(f).read().splitlines()
    truth, seed = txt[0].split()[0], txt[0].split()[1]
    wb = float(re.search(r"whole-record ([\d.]+)x", txt[0]).group(1))
    rk = [(x.rsplit(" ", 1)[0], float(x.rsplit(" ", 1)[1])) for x in txt[-1][len("ranked: "):].split(", ")]
    nm, amb = whole_record_name({"ranking": [{"name": n, "gain": g, "rmse": 1 - g} for n, g in rk]}, T)
    if wb > 2.0:
        nm, amb = None, []
    ok = (nm is None) if truth == "none" else (nm == truth or truth in amb)
    k = "clean" if truth == "none" else "effect"
    tot[k] = tot.get(k, 0) + 1; tot[k + " ok"] = tot.get(k + " ok", 0) + ok
    if truth != "none":
        tot["wrong"] = tot.get("wrong", 0) + (nm is not None and not ok)
    print(f"{truth:20s} {seed:6s} base {wb:5.2f}  named {nm or 'none':20s} {','.join(amb):30s} {'ok' if ok else '--'}")
print(tot)
