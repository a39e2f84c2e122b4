"""Per output sign: screened start (rule memories) and then fitted_memory_start; which sign wins after the memory search?"""
import sys, time, json, numpy as np
import smafl_jax as sj
from smafl_jax.identify import screen_start
from smafl_jax.identify._choose import fitted_memory_start  # private: probe
from smafl_jax.identify._split import split_masks  # private: probe
from smafl_jax.report._report_fit import build_model  # private: probe
path = sys.argv[1]
rec = sj.load_record(path)
train, val = split_masks(rec, "time", 0.3)[:2] if False else (None, None)
n = len(rec); ntr = int(0.7 * n)
w = np.zeros(n); w[:ntr] = 1.0
data = [(np.asarray(rec.u), np.asarray(rec.y), rec.dt)]
for sign in ("rises", "falls"):
    t0 = time.time()
    m0 = build_model("cascade", rec)
    m, table, info = screen_start(m0, data, [w], orientation=sign, memory="rule")
    r = sj.fit(m, rec, solver=None, init=None, weights=w)
    got = fitted_memory_start(m, data, [w])
    lf = sj.fit(got[0], rec, solver=None, init=None, weights=w).loss if got else np.nan
    print(f"{sign}: screened rule loss {r.loss:.5g}; fitted memory ({got[1] if got else None}) loss {lf:.5g}; {time.time()-t0:.0f} s", flush=True)
