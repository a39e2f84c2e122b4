"""Would `smafl simulate` on the whole record warn that the model's output leaves its fitted range? (plant B fits)"""
import sys, json, glob
from pathlib import Path
import numpy as np
import smafl_jax as sj
from smafl_jax.models._range import output_check, model_range_checks
for d in sorted(glob.glob(sys.argv[1])):
    d = Path(d)
    fj = next(d.rglob("fit.json"), None)
    if fj is None: continue
    doc = json.loads(fj.read_text()); model = sj.load_model(fj)
    tr = sj.load_record(d / "first70.csv"); full = sj.load_record(d / "full.csv")
    data = dict(doc["data"]); data.setdefault("output_range", [float(np.nanmin(tr.y)), float(np.nanmax(tr.y))])
    h0 = len(tr)
    yh = np.asarray(sj.simulate(model, full.u, full.dt))
    checks = model_range_checks(model, data, full.u[h0:] if False else full.u, full.dt)
    inside = not any(c.get("warning") for c in checks if c.get("what") in ("input", "effective input"))
    c = output_check(yh, data["output_range"], input_inside=inside, dt=full.dt)
    for k in checks:
        if k.get("checked") and "max_above" in k: print("   ", k["what"], "above %.3f below %.3f of span" % (k["max_above"]/(k["fitted_range"][1]-k["fitted_range"][0]), k["max_below"]/(k["fitted_range"][1]-k["fitted_range"][0])))
    held = np.sqrt(np.mean((yh[h0:] - full.y[h0:]) ** 2)) / 0.005
    print(f"{d.name:40s} held {held:8.1f}x  out {c['max_outside_spans']:.2f} spans  inside {inside}  {'WARN' if 'warning' in c else ''}")
