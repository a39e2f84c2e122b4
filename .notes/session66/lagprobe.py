"""Whole-record base with the other drive lag: python lagprobe.py PKL"""
import sys, pickle, dataclasses
from smafl_jax.diagnosis import _diagnose as D
g = pickle.load(open(sys.argv[1], "rb"))
rec, base, noise = g["record"], g["base"], g["case"]["noise_rms_measured"]
w = D.whole_record_split(rec)
full = D.Split(w.kind, w.rule, w.train, w.train, w.train_labels, w.train_labels)
th = D.thermal_of(base.base)
out = []
for lag in (th.lag, 1 - th.lag):
    b0 = dataclasses.replace(base.base, thermal=dataclasses.replace(th, lag=lag))
    b = D.refine_model(D.fit_extended(D.ExtendedModel.of(b0), [], full)[0], full)
    out.append(f"lag {lag}{' (split choice)' if lag == th.lag else ''}: {D.score(b, full.train)[0]['rmse']/noise:.3f}x")
print(g["truth"], g["seed"], g["case"]["rate_hz"], "; ".join(out))
