"""Session 63: is the diagnosis base deterministic?  Prints the held-out RMSE after each base stage for one
independent record.  python base_determinism.py TRUTH SEED"""
import sys, tempfile, hashlib
import numpy as np
sys.path.insert(0, "experiments")
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D

truth, seed = sys.argv[1], int(sys.argv[2])
with tempfile.TemporaryDirectory() as tmp:
    path, case = ie.write_effect_record(tmp, truth, seed)
    print("csv md5", hashlib.md5(open(path, "rb").read()).hexdigest())
    rec = sj.load_record(path)
noise = case["noise_rms_measured"]
split = D.make_split(rec)
base0, _ = D.choose_base(rec)
base0, screened = D.screened_base(base0, split)
h = lambda m: D._held(m, split)["rmse"] / noise
print("screened", h(base0), flush=True)
base, info = D.fit_extended(base0, [], split)
print("fit_extended", h(base), flush=True)
base, cs, _ = D.refined_base(base, base0, split)
print("refined", h(base), "cand_start", h(cs), flush=True)
base, passes = D.converged_base(base, split)
print("converged", h(base), passes, flush=True)
