"""Base stage of the diagnosis only: per variant training BIC and held-out RMSE; which each rule picks."""
import json, sys, time, tempfile
sys.path.insert(0, "/work/main"); sys.path.insert(0, "/work/main/experiments")
import numpy as np
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D

out = sys.argv[1]
jobs = [a.split(":") for a in sys.argv[2:]]
with open(out, "a") as f:
    for truth, seed in jobs:
        t0 = time.time()
        with tempfile.TemporaryDirectory() as d:
            path, case = ie.write_effect_record(d, truth, int(seed))
            rec = sj.load_record(path)
        base0, _ = D.choose_base(rec)
        split = D.make_split(rec)
        base0, screened = D.screened_base(base0, split)
        base, info = D.fit_extended(base0, [], split)
        if screened is None:
            continue
        _, _, doc = D.refined_base(base, base0, split)
        noise = case["noise_rms_measured"]
        held = doc["heldout_rmse"]; tr = doc["train"]
        by_held = min(held, key=lambda k: held[k] if np.isfinite(held[k]) else np.inf)
        by_bic = min(tr, key=lambda k: tr[k]["bic"] if np.isfinite(tr[k]["bic"]) else np.inf)
        row = {"truth": truth, "seed": int(seed), "by_held": by_held, "by_bic": by_bic,
               "held_over_noise": {k: v / noise for k, v in held.items()}, "train": tr, "s": time.time() - t0}
        f.write(json.dumps(row) + "\n"); f.flush()
        print(truth, seed, by_held, by_bic, {k: round(v / noise, 3) for k, v in held.items()}, {k: (round(v["bic"], 1), v["k"]) for k, v in tr.items()}, f"{time.time()-t0:.0f}s", flush=True)
