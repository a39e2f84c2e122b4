"""Replay the at-floor naming (`rename` with no gates' selection) on whole_only.py outputs and the diagnosis JSONs of
the same records: python floor_replay.py WHOLEDIR DIAGDIR"""
import glob, json, re, sys
from smafl_jax.diagnosis import rename
wdir, ddir = sys.argv[1], sys.argv[2]
diag = {}
for f in glob.glob(f"{ddir}/*.json"):
    if not f.endswith(".partial.json"):
        for r in json.load(open(f))["rows"]:
            diag[(r["truth"], r["case"]["requested_seed"])] = r
for f in sorted(glob.glob(f"{wdir}/*.txt")):
    txt = open(f).read().splitlines()
    if len(txt) < 3:
        continue
    truth, seed = txt[0].split()[0], int(txt[0].split()[1])
    wb = float(re.search(r"whole base ([\d.]+)x", txt[0]).group(1))
    rk = [(x.rsplit(" ", 1)[0], float(x.rsplit(" ", 1)[1])) for x in txt[1][len("ranked: "):].split(", ")]
    r = diag.get((truth, seed))
    floor = r is not None and any("noise floor" in (c.get("decision") or "") for c in r["candidates"])
    held = {c["name"]: c["heldout_gain"] for c in (r or {}).get("candidates", []) if c.get("heldout_gain") is not None}
    doc = {"base_rmse": wb, "ranking": [{"name": n, "gain": g, "rmse": wb * (1 - g)} for n, g in rk]}
    (sel, amb), _ = rename(doc, [], [], min_gain=0.05, noise_sd=1.0, heldout_gain=held)
    ok = (not sel) if truth == "none" else bool(sel) and (truth in sel or truth in amb)
    print(f"{truth:18s} {seed:5d} whole base {wb:.2f} gates-at-floor {floor!s:5s} gates {'+'.join((r or {}).get('selected_new') or []) or 'none':18s} "
          f"whole-only {'+'.join(sel) or 'none':18s} {','.join(amb):25s} {'ok' if ok else '--'}  top {rk[0][0]} {rk[0][1]:+.3f} (held {held.get(rk[0][0], float('nan')):+.3f})")
