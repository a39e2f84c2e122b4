"""Trace the LM loss per step of one class (stall off): python lm_trace_probe.py REC.csv MODEL TRACE.json"""

import json
import os
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import jax
import numpy as np
import optimistix as optx

import smafl_jax as sj
from smafl_jax.identify import _fit  # private: probe

trace = []
orig = _fit._make_optx_solver


def cb(**kw):
    trace.append({k: float(np.asarray(v)) for k, v in kw.items() if np.ndim(np.asarray(v)) == 0})


def make(name, rtol, atol, stall=True):
    if name == "lm":
        return optx.LevenbergMarquardt(
            rtol=rtol,
            atol=atol,
            verbose=lambda **kw: jax.debug.callback(
                cb, **{k: v[1] for k, v in kw.items() if k not in ("y", "y_last_accepted_step")}
            ),
        )
    return orig(name, rtol, atol)


_fit._make_optx_solver = make
from smafl_jax.report import fit_record  # noqa: E402  (after the solver patch)

rec = sj.load_record(sys.argv[1])
t0 = time.perf_counter()
m, doc, _ = fit_record(rec, model=sys.argv[2], thresholds=True, tilts=True)
print("wall", time.perf_counter() - t0, "val", doc["metrics"]["validation"]["rmse"], "train", doc["metrics"]["train"]["rmse"])
json.dump(trace, open(sys.argv[3], "w"))
