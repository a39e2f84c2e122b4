"""Records where session 47's class rule (`_report_fit._prefers_default`: the EUPI cascade kept over a class that wins
validation by < 2x while fitting training no better) changes the kept class.

python .notes/session47/flips.py plantb FILE.jsonl     (fit_plant_b.py rows: fit.json structure_choice inside)
python .notes/session47/flips.py matrix FILE.json      (base_fit_before_after.py rows with candidates_train)
Prints each flipped record: the class the validation block alone keeps, and the names to rerun with the old code.
"""
import json
import sys

kind, path = sys.argv[1], sys.argv[2]
if kind == "plantb":
    rows = [json.loads(line) for line in open(path)]
    items = []
    for r in rows:
        c = r["fit"]["structure_choice"]["candidates"]
        items.append((r["name"], {x["structure"]: x["validation"]["rmse"] for x in c}, {x["structure"]: x["train_rmse"] for x in c}, r))
else:
    rows = json.load(open(path))
    items = [(f"{r['cell']}|{r['seed']}", r["candidates"], r["candidates_train"], r) for r in rows]
for name, val, train, r in items:
    best = min(val, key=val.get)
    if best != "cascade" and val["cascade"] < 2 * val[best] and train["cascade"] <= train[best]:
        held = r.get("heldout_x_noise", r.get("held"))
        print(f"{name}: validation keeps {best} ({val[best]:.4g} vs cascade {val['cascade']:.4g}; training {train[best]:.4g} vs "
              f"{train['cascade']:.4g}); rule keeps cascade, held out {held:.2f}x")
