"""Session 68: `smafl fit`'s default cascade (split fit only, same last-30 % time block as diagnose) on indep effect
records: held-out RMSE over the estimated noise.  python fitfloor.py TRUTH:SEED ... (appends to experiments/results/diagnose_clean_plant_a_session68/fitfloor_rows.jsonl)"""
import sys, json, tempfile, time
sys.path.insert(0, "experiments")
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.report._report_fit import _fit_structure  # private: the default class alone, as auto fits it
for arg in sys.argv[1:]:
    truth, seed = arg.split(":"); seed = int(seed)
    t0 = time.time()
    with tempfile.TemporaryDirectory() as tmp:
        path, case = ie.write_effect_record(tmp, truth, seed)
        rec = sj.load_record(path)
        m, doc, _ = _fit_structure(rec, model="auto", split="time", refit=False)
    met = doc["metrics"]
    row = {"truth": truth, "seed": seed, "val_ratio": met["noise"]["validation_ratio"], "train_ratio": met["noise"]["train_ratio"],
           "val_rmse": met["validation"]["rmse"], "noise_sd": met["noise"]["sd"], "seconds": time.time() - t0}
    print(json.dumps(row), flush=True)
    open("experiments/results/diagnose_clean_plant_a_session68/fitfloor_rows.jsonl", "a").write(json.dumps(row) + "\n")
