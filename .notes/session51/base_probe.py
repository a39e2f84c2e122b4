"""Probe: the diagnosis base (A) as today vs (B) screened on the record's full time axis (fold score) with the other
hysteresis input refined too, kept when lower on held-out and no higher on training (as `smafl fit` does)."""
import sys, json, time, tempfile
sys.path.insert(0, "/work/main"); sys.path.insert(0, "/work/main/experiments")
import numpy as np
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import choose_base, fit_extended, make_split, screened_base
from smafl_jax.diagnosis._diagnose import refined_base, converged_base, _held, _train_sse  # private: probe
from smafl_jax.identify._choose import screen_start  # private: probe
name, seed = sys.argv[1], int(sys.argv[2])
path, case = ie.write_effect_record(tempfile.mkdtemp(), name, seed)
rec = sj.load_record(path)
split = make_split(rec)
noise = case["noise_rms_measured"]
base0 = choose_base(rec)[0]
row = {"truth": name, "seed": seed, "drive": case.get("drive"), "start": case.get("start"), "n": len(rec.u)}
ntr = sum(int(s.mask.sum()) for s in split.train)
def run(st):
    b = fit_extended(st, [], split)[0]
    b, _, doc = refined_base(b, st, split)
    b, _ = converged_base(b, split)
    return {"sees": getattr(st, "sees", None), "held": _held(b, split)["rmse"] / noise,
            "train": float(np.sqrt(_train_sse(b, split.train) / ntr)) / noise, "memory": doc["chosen"]}
t0 = time.time()
row["A"] = run(screened_base(base0, split)[0]); row["A_s"] = time.time() - t0
tr, te = split.train[0], split.test[0]
n0 = len(tr.u)
assert len(split.train) == 1 and np.allclose(te.u[:n0], tr.u), "train is not a prefix of the test axis"
w = np.zeros(len(te.u)); w[:n0] = tr.mask
t0 = time.time()
m, _, info = screen_start(base0, [(te.u, te.y, te.dt)], [w], val_weights=[te.mask.astype(float)], memory="rule", other_inputs=True)
row["B"] = run(m)
alts = info.get("input_alternatives", [])
if alts:
    row["B_other"] = run(alts[0])
b, o = row["B"], row.get("B_other")
row["B_pick"] = o if (o and o["held"] < b["held"] and o["train"] <= b["train"]) else b
row["B_s"] = time.time() - t0
print(json.dumps(row), flush=True)
