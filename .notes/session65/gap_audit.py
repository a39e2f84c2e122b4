"""Truth's held-out gain against the base's generalisation gap (held-out / training RMSE) over stored blind diagnoses.
python gap_audit.py DIR ..."""
import glob, json, os, sys, collections
import numpy as np
seen = set(); rows = []
for d in sys.argv[1:]:
    for f in sorted(glob.glob(f"{d}/*.json")):
        if f.endswith(".partial.json"):
            continue
        try:
            rr = json.load(open(f))["rows"]
        except (KeyError, json.JSONDecodeError, TypeError):
            continue
        for r in rr:
            key = (r["truth"], r["case"]["requested_seed"])
            if key in seen or "base_train_rmse" not in r:
                continue
            seen.add(key)
            cands = {x["name"]: x for x in r["candidates"]}
            t = cands.get(r["truth"])
            gap = r["base_heldout_rmse"] / r["base_train_rmse"]
            ok = (not r["selected_new"]) if r["truth"] == "none" else (r["truth"] in (r["selected_new"] or []) or r["truth"] in (r["ambiguous_new"] or []))
            rows.append((r["truth"], key[1], gap, r["base_train_over_noise"], None if t is None else t.get("heldout_gain"), ok, r["selected_new"]))
bins = [(0, 1.5), (1.5, 2.5), (2.5, 4), (4, 1e9)]
print("| base held-out / training | catalogued-effect records | truth's candidate holds out better than the base (gain > 0.05) | truth named | clean records | clean right |")
print("|---|---|---|---|---|---|")
for lo, hi in bins:
    eff = [r for r in rows if lo <= r[2] < hi and r[0] != "none" and r[4] is not None]
    cl = [r for r in rows if lo <= r[2] < hi and r[0] == "none"]
    g = sum(r[4] > 0.05 for r in eff); ok = sum(r[5] for r in eff)
    print(f"| {lo:g}-{hi:g} | {len(eff)} | {g} ({100*g/max(len(eff),1):.0f} %) | {ok} ({100*ok/max(len(eff),1):.0f} %) | {len(cl)} | {sum(r[5] for r in cl)} |")
print()
print("| base training RMSE / noise | catalogued-effect records | truth gains > 0.05 | truth named | clean records | clean right |")
print("|---|---|---|---|---|---|")
for lo, hi in [(0, 1.15), (1.15, 1.5), (1.5, 2.5), (2.5, 5), (5, 1e9)]:
    eff = [r for r in rows if lo <= r[3] < hi and r[0] != "none" and r[4] is not None]
    cl = [r for r in rows if lo <= r[3] < hi and r[0] == "none"]
    g = sum(r[4] > 0.05 for r in eff); ok = sum(r[5] for r in eff)
    print(f"| {lo:g}-{hi:g} | {len(eff)} | {g} ({100*g/max(len(eff),1):.0f} %) | {ok} ({100*ok/max(len(eff),1):.0f} %) | {len(cl)} | {sum(r[5] for r in cl)} |")
print()
ab = [r for r in rows if r[3] < 1.15 and r[0] != "none" and r[4] is not None]
for lo, hi in [(0, 1.5), (1.5, 3), (3, 1e9)]:
    s = [r for r in ab if lo <= r[3] * r[2] < hi]
    print(f"base training <= 1.15x noise, held out {lo:g}-{hi:g}x noise: {len(s)} records, truth gains {sum(r[4] > 0.05 for r in s)}, named {sum(r[5] for r in s)}; selected instead: {collections.Counter('+'.join(r[6]) or 'none' for r in s if not r[5]).most_common()}")
