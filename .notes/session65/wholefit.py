"""Whole-record fits: the base and candidates refitted on every sample (no held-out part); training RMSE gain and BIC.
Feasibility probe for a likelihood-ratio test calibrated on null records. python wholefit.py PKL [NAME ...]"""
import sys, pickle, time
import numpy as np
from smafl_jax.diagnosis import _diagnose as D
g = pickle.load(open(sys.argv[1], "rb"))
names = sys.argv[2:] or [g["name"]]
rec, base, noise = g["record"], g["base"], g["case"]["noise_rms_measured"]
w = D.whole_record_split(rec)
full = D.Split(w.kind, w.rule, w.train, w.train, w.train_labels, w.train_labels)  # test = train: refine_model's gate on the training loss
t0 = time.time()
b = D.refine_model(D.fit_extended(base, [], full)[0], full)
ic_b = D.information_criteria(b, full.train, k=D.n_refined_parameters(b))
rb = D.score(b, full.train)[0]["rmse"]
print(f"{g['truth']} s{g['seed']} base whole-record {rb/noise:.3f}x noise (split base train {D._metrics_pair(base, g['split'])[0]['rmse']/noise:.2f}, held {D._metrics_pair(base, g['split'])[1]['rmse']/noise:.2f}) {time.time()-t0:.0f} s", flush=True)
if names == ["ALL"]:
    names = [n for n in D.applicable_effects(b, full, D.is_rate_free(rec)) if n != D.NONLOCAL_MEMORY["name"]]
rows = []
for nm in names:
    t0 = time.time()
    c = D.refine_model(D.fit_extended(b, [nm], full)[0], full)
    rc = D.score(c, full.train)[0]["rmse"]
    ic = D.information_criteria(c, full.train, k=D.n_refined_parameters(c))
    print(f"   {nm:20s} {rc/noise:.3f}x  gain {1 - rc/rb:+.3f}  dBIC {ic['bic'] - ic_b['bic']:+.1f}  {D._effect_params(c.get(nm))}  {time.time()-t0:.0f} s", flush=True)
    rows.append((1 - rc / rb, nm))
print("ranked:", ", ".join(f"{n} {gn:+.3f}" for gn, n in sorted(rows, reverse=True)))
