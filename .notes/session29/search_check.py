"""Session 29: identify._memory_search.search_memory on the plant's TRUE hysteresis input (static EUPI, default grid),
then the LM with thresholds and tilts trained.  python search_check.py SEED CELL"""
import json, sys, time
import numpy as np
sys.path.insert(0, "/work/main/tests")
import indep_plant as ip
import smafl_jax as sj
from smafl_jax.identify import default_trainable
from smafl_jax.identify._memory_search import search_memory  # private: checked before it is wired in
from smafl_jax.identify._fit import init_linear  # private: the profiled gains

seed, cell = int(sys.argv[1]), sys.argv[2]
kw = {"cold": dict(drive="random_levels", rate_hz=20, start="cold", orientation="length"),
      "warm": dict(drive="random_levels", rate_hz=10, start="warm")}[cell]
r = ip.make_record(seed, minutes=20, **kw)
h0, sd, dt = r["heldout_start"], r["noise_sd"], r["dt"]
x = np.asarray(r["sim"]["x_h"]); y = np.asarray(r["y"])
w = np.zeros(len(x)); w[:h0] = 1.0
sign = 1 if r["truth"]["sensor"]["orientation"] == "displacement" else -1
m0 = sj.EUPI.from_range(float(x[:h0].min()), float(x[:h0].max()), orientation=sign).with_fitted_memory()
data = [(x, y, dt)]
m0 = init_linear(m0, data, weights=[w])
t0 = time.time()
got = search_memory(m0, data, [w])
print("search s", round(time.time() - t0, 2), "loss", None if got is None else got[1])
m1 = got[0] if got else m0
res = sj.fit(m1, data, weights=[w], init=None, trainable=default_trainable(m1, thresholds=True, tilts=True))
e = np.asarray(sj.simulate(res.model, x, dt)) - y
print(json.dumps(dict(seed=seed, cell=cell, train=float(np.sqrt(np.mean(e[:h0] ** 2)) / sd), held=float(np.sqrt(np.mean(e[h0:] ** 2)) / sd))))
