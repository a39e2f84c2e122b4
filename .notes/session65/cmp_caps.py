"""Base and true-effect candidate held out, before (DIR_OLD) and after (DIR_NEW): python cmp_caps.py DIR_OLD DIR_NEW"""
import sys, glob, os, pickle
import numpy as np
from smafl_jax.diagnosis import _diagnose as D
old, new = sys.argv[1], sys.argv[2]
for f in sorted(glob.glob(f"{new}/*.pkl")):
    row = []
    for d in (old, new):
        p = os.path.join(d, os.path.basename(f))
        if not os.path.exists(p):
            row.append(None); continue
        g = pickle.load(open(p, "rb")); noise = g["case"]["noise_rms_measured"]; sp = g["split"]
        b = D._metrics_pair(g["base"], sp); j = D._metrics_pair(g["joint"], sp)
        row.append((b[0]["rmse"] / noise, b[1]["rmse"] / noise, j[0]["rmse"] / noise, j[1]["rmse"] / noise, 1 - j[1]["rmse"] / b[1]["rmse"], D._effect_params(g["joint"].get(g["name"]))))
    name = os.path.basename(f)[:-4]
    for lab, r in zip(("old", "new"), row):
        if r:
            print(f"{name:24s} {lab} base {r[0]:.2f}/{r[1]:.2f} cand {r[2]:.2f}/{r[3]:.2f} gain {r[4]:+.2f} {({k: round(v, 4) for k, v in r[5].items()})}")
