"""Session 63: table and tallies of blind diagnoses (experiments/diagnose_independent.py JSON files).
Catalogued truth: right when the truth is selected or in the ambiguous set; clean ("none"): right when nothing is
selected; uncatalogued truth (experiments/indep_effects.py UNCATALOGUED_CASES): right when no catalogue effect is
selected, and the unexplained report is scored apart (structure left; strongest correlate as expected).
python .notes/session63/table.py DIR [DIR ...]"""
import collections, glob, json, os, sys
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "experiments"))
import indep_effects as ie

tally = collections.Counter()
print("| truth | seed | variant | drive, start, rate | effect / noise | base train / held-out (noise) | selected | ambiguous / unspecific | right | unexplained: structure left, strongest correlate (corr), held-out before -> after |")
print("|---|---|---|---|---|---|---|---|---|---|")
rows = []
for d in sys.argv[1:]:
    for f in sorted(glob.glob(f"{d}/*.json")):
        if f.endswith(".partial.json"):
            continue
        rows += json.load(open(f))["rows"]
for r in sorted(rows, key=lambda r: (r["truth"], r["case"]["requested_seed"])):
    c, t, sel = r["case"], r["truth"], r["selected_new"]
    amb = r["ambiguous_new"] or []
    u = r.get("unexplained") or {}
    if t in ie.UNCATALOGUED_TRUTHS:
        ok = not sel
        exp = ie.EXPECTED_CORRELATE.get((t, c["variant"]))
        corr_ok = exp is not None and exp in str(u.get("strongest_correlate"))
        tally["uncat"] += 1
        tally["uncat right"] += ok
        tally["uncat structure left"] += bool(u.get("structure_left"))
        tally["uncat correlate named"] += corr_ok
        tally["uncat correlate expected"] += exp is not None
    elif t == "none":
        ok = not sel
        tally["clean"] += 1
        tally["clean right"] += ok
    else:
        ok = bool(sel) and (t in sel or t in amb)
        tally["effect"] += 1
        tally["effect right"] += ok
        tally["effect wrong name"] += bool(sel) and not ok
        tally["effect none"] += not sel
    ux = "n/a" if not u else (
        f"{'left' if u.get('structure_left') else 'none left'}, {u.get('strongest_correlate')} ({u.get('strongest_corr') or 0:+.2f}), "
        f"{u.get('heldout_rmse_before') or 0:.4g} -> {u.get('heldout_rmse_after') or 0:.4g}{'' if u.get('predictable') else ' (not predictable)'}")
    eff = c.get("effect_over_noise")
    print(f"| {t} | {c['requested_seed']} | {c.get('variant') or ''} | {c['drive']}, {c['start']}, {c['rate_hz']:.1f} Hz | "
          f"{'' if eff is None else f'{eff:.1f}'} | {r['base_train_over_noise']:.2f} / {r['base_heldout_over_noise']:.2f} | "
          f"{'+'.join(sel) or 'none'} | {', '.join(amb or r.get('unspecific_new') or []) or '-'} | {'yes' if ok else 'no'} | {ux} |")
print()
print(dict(tally))
