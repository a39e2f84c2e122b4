import sys, glob, json
sys.path.insert(0, ".notes/session67")
R = "experiments/results/"
dirs = [R + "diagnose_independent_session66", R + "diagnose_independent_session66/seed13", R + "diagnose_independent_session67/new", R + "diagnose_independent_session67/seed14", R+"diagnose_independent_session67/old"]
for d in dirs:
    for f in sorted(glob.glob(d + "/*.json")):
        for r in json.load(open(f))["rows"]:
            nm = r.get("naming")
            if not nm or not nm.get("ranking"):
                continue
            held = {c["name"]: c.get("heldout_gain") for c in r["candidates"]}
            sp = (nm["split_selected"] or [None])[0]
            named = nm.get("named")
            print(f"{d[-12:]:12s} {r['truth']:18s} {r['case']['requested_seed']:5d} gates {str(sp):20s} named {str(named):20s} held(named) {held.get(named) if named else None!s:.6s}  held(gates) {held.get(sp) if sp else None!s:.6s} base/noise {nm.get('base_over_noise') or 0:.2f}")
