"""Held-out / noise of the saved (whole-record refit) model vs the split model (trained on the first 70 % of first70.csv),
both simulated over the full record of each class_choice_confirm fit in /tmp/cf_work (session 22's fits)."""
import json, sys
from pathlib import Path
import numpy as np
import smafl_jax as sj

rows = []
for d in sorted(Path("/tmp/cf_work").iterdir()):
    z = d / "full.npz"
    if not z.exists():
        continue
    z = np.load(z)
    h0, sd = int(z["h0"]), float(z["sd"])
    for fd in sorted(d.glob("fit_*")):
        fj = fd / "fit.json"
        if not fj.exists():
            continue
        doc = json.loads(fj.read_text())
        m = sj.load_model(fj)
        sm = sj.model_from_dict(doc["split_model"] or doc["model"])
        out = {"name": d.name, "cls": fd.name[4:]}
        for lab, mod in (("final", m), ("split", sm)):
            yh = np.asarray(sj.simulate(mod, z["u"], float(z["dt"])))
            out[lab] = float(np.sqrt(np.mean((yh[h0:] - z["y"][h0:]) ** 2)) / sd)
        out["rejected"] = any("refinement lowered the training error" in n for n in doc["notes"])
        print(json.dumps(out), flush=True)
