"""Session 29: per-operator search of the EUPI's initial operator memory (coordinate-wise variable projection) before
the LM, on the plant's TRUE hysteresis input (plant A random_levels, 20 min).  python memory_search.py SEED CELL"""
import dataclasses, json, sys, time
import numpy as np
from scipy.optimize import lsq_linear
sys.path.insert(0, "/work/main/tests")
import indep_plant as ip
import jax.numpy as jnp
import smafl_jax as sj
from smafl_jax.identify import default_trainable

seed = int(sys.argv[1]); cell = sys.argv[2] if len(sys.argv) > 2 else "warm"
kw = {"cold": dict(drive="random_levels", rate_hz=20, start="cold", orientation="length"),
      "warm": dict(drive="random_levels", rate_hz=10, start="warm")}[cell]
r = ip.make_record(seed, minutes=20, **kw)
h0, sd, dt = r["heldout_start"], r["noise_sd"], r["dt"]
x = np.asarray(r["sim"]["x_h"]); y = np.asarray(r["y"])
lo_x, top = float(x[:h0].min()), float(x[:h0].max())
w = np.zeros(len(x)); w[:h0] = 1.0
sign = 1 if r["truth"]["sensor"]["orientation"] == "displacement" else -1
FR = np.linspace(0.0, 1.0, 11)

def play_cols(s, r_, a_, y0):
    """numpy play bank, (T, n) for initial states y0 (n,)"""
    F = np.array(y0, float); out = np.empty((len(s), len(r_)))
    for k, sk in enumerate(s):
        F = np.maximum(sk - r_, np.minimum(a_ * (sk + r_), F)); out[k] = F
    return out

def search(m, sweeps=2):
    s = np.asarray(m.normalise(jnp.asarray(x)))[:h0]
    rr, aa = (np.asarray(v) for v in m._bank())
    lo0, up0 = s[0] - rr, aa * (s[0] + rr)
    n = len(rr)
    # every operator's column for every candidate fraction: (K, T, n)
    cand = np.stack([play_cols(s, rr, aa, lo0 + f * (up0 - lo0)) for f in FR])
    base = np.asarray(m.features(jnp.asarray(x)))[:h0]
    nonneg = m.nonnegative_columns()
    lb = np.where(nonneg, 0.0, -np.inf); ub = np.full(len(nonneg), np.inf)
    k_of = np.full(n, len(FR) - 1)  # start: descended (fraction 1)
    def design(k_of):
        A = base.copy()
        A[:, 1:1 + n] = sign * cand[k_of, :, np.arange(n)].T
        return A
    def sse(A):
        return float(lsq_linear(A, y[:h0], bounds=(lb, ub), method="bvls").cost)
    best = sse(design(k_of))
    for sweep in range(sweeps):
        for i in range(n):
            trials = []
            for k in range(len(FR)):
                kk = k_of.copy(); kk[i] = k
                trials.append(sse(design(kk)))
            k_best = int(np.argmin(trials))
            if trials[k_best] < best - 1e-12:
                best = trials[k_best]; k_of[i] = k_best
        print("sweep", sweep, "rmse/sd", np.sqrt(2 * best / h0) / sd, flush=True)
    f = np.clip(FR[k_of], 0.01, 0.99)
    return dataclasses.replace(m, memory=jnp.asarray(np.log(f / (1 - f))))

def score(name, m, **kw):
    t0 = time.time()
    res = sj.fit(m, [(x, y, dt)], weights=[w], **kw)
    e = np.asarray(sj.simulate(res.model, x, dt)) - y
    print(json.dumps(dict(seed=seed, cell=cell, variant=name, train=float(np.sqrt(np.mean(e[:h0] ** 2)) / sd),
                          held=float(np.sqrt(np.mean(e[h0:] ** 2)) / sd), s=round(time.time() - t0, 1))), flush=True)
    return res.model

m0 = sj.EUPI.from_range(lo_x, top, n_sym=8, n_alpha=4, n_asym=4, orientation=sign).with_init("fitted")
tr = default_trainable(m0, thresholds=True, tilts=True)
score("default grid, thresholds+tilts trained", m0, trainable=tr)
t0 = time.time(); ms = search(m0); print("search s", round(time.time() - t0, 1))
score("memory searched, then thresholds+tilts trained", ms, trainable=tr)
# iterate: search again at the trained thresholds
