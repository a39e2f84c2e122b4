"""Whole-record refit of a saved fit: fresh screening (what `_refit_whole` does when the split's refinement was rejected,
and what the saved fit.json holds then) vs a warm start from the split model (LM on every sample).  Scored on the last
30 % of the full record (never fitted) and on the whole-record training RMSE (what a rule could use).
    python warm_refit_probe.py CLS [NAME_SUBSTRING] > out.jsonl      (fits of /tmp/cf_work from class_choice_confirm)"""
import json, sys, time
from pathlib import Path
import numpy as np
import smafl_jax as sj
from smafl_jax.identify._decimate import fit_view  # private: the same view the fit used
from smafl_jax.report._report_fit import _polish, _refit_whole  # private: the refit under study

cls = sys.argv[1]
sub = sys.argv[2] if len(sys.argv) > 2 else ""
for d in sorted(Path("/tmp/cf_work").iterdir()):
    fj = d / f"fit_{cls}" / "fit.json"
    if sub not in d.name or not fj.exists():
        continue
    z = np.load(d / "full.npz")
    h0, sd, u, y, dt = int(z["h0"]), float(z["sd"]), z["u"], z["y"], float(z["dt"])
    doc = json.loads(fj.read_text())
    rec = sj.load_record(d / "first70.csv")
    split = sj.model_from_dict(doc["split_model"] or doc["model"])
    final = sj.load_model(fj)
    st = doc["settings"]
    t0 = time.time()
    view, _, vinfo = fit_view(rec, split, [np.ones(len(rec), bool)])
    warm = _refit_whole(view, st["structure"], split, None, st["thermal_start"], "kept", "lm", st["max_steps"], True, True,
                        False, st["memory_used"], st["gain_prior"])
    if vinfo:
        warm = _polish(warm, rec, np.ones(len(rec), bool), "lm", True, True, False, st["gain_prior"])
    out = {"name": d.name, "cls": cls, "refinement": doc["solver"].get("refinement"), "sec": round(time.time() - t0, 1)}
    for lab, m in (("final", final), ("warm", warm)):
        yh = np.asarray(sj.simulate(m, u, dt))
        out[lab + "_held"] = float(np.sqrt(np.mean((yh[h0:] - y[h0:]) ** 2)) / sd)
        out[lab + "_train"] = float(np.sqrt(np.mean((yh[:h0] - y[:h0]) ** 2)) / sd)
    print(json.dumps(out), flush=True)
