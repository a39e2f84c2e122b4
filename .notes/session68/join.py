import sys, json, collections
sys.path.insert(0, ".notes/session67")
import io, contextlib
with contextlib.redirect_stdout(io.StringIO()):
    import tally as T  # prints its table at import
fit = {(r["truth"], r["seed"]): r for r in map(json.loads, open("experiments/results/diagnose_clean_plant_a_session68/fitfloor_rows.jsonl"))}
for key, r in sorted(T.recs.items()):
    if key not in fit: continue
    s, a = T.floor.get(key) or T.answer(r, 5.0)
    k = T.ok(key[0], s, a)
    nm = r.get("naming") or {}
    held = {c["name"]: c.get("heldout_gain") for c in r["candidates"]}
    f = fit[key]
    flag = "FLOOR" if f["val_ratio"] <= 1.2 else ""
    print(f"{key[0]:18s} {key[1]:5d} now {'+'.join(s) or 'none':22s} {'ok' if k else '--'}  diag base {r['base_heldout_over_noise']:6.2f}  fit {f['val_ratio']:6.2f} {flag:5s} rank {'yes' if nm.get('ranking') else 'no ':3s} "
          + (f"leader {nm['ranking'][0]['name']} {nm['ranking'][0]['gain']:+.3f} held {held.get(nm['ranking'][0]['name'])!s:.6s} whole {nm.get('base_over_noise') or 0:.2f}" if nm.get('ranking') else ""))
