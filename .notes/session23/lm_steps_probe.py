"""How much of the Gaussian-Preisach cascade's joint LM (300-step cap) moves the fit?  The split fit (refit off) with
max_steps in STEPS on one plant-B record's first 70 %: training/validation RMSE of the split, steps taken, seconds.
    python lm_steps_probe.py NAME OUT.jsonl"""
import json, sys, time
from pathlib import Path
import smafl_jax as sj
from smafl_jax.report import fit_record

name, out = sys.argv[1], sys.argv[2]
rec = sj.load_record(Path("/tmp/cf_work") / name / "first70.csv")
for steps in (0, 50, 100, 200, 300):
    t0 = time.perf_counter()
    _, doc, _ = fit_record(rec, model="cascade-preisach-gauss", max_steps=steps, refit=False)
    row = {"name": name, "max_steps": steps, "seconds": time.perf_counter() - t0, "train": doc["metrics"]["train"]["rmse"],
           "val": doc["metrics"]["validation"]["rmse"], "n_steps": doc["solver"].get("n_steps"),
           "refinement": doc["solver"].get("refinement"), "message": doc["solver"].get("message", "")[:50]}
    print(json.dumps(row), flush=True)
    with open(out, "a") as f:
        f.write(json.dumps(row) + "\n")
