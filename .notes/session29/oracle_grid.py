"""Session 29: static EUPI on the plant's TRUE hysteresis input x_h (plant A, random_levels warm 10 Hz, 20 min):
the default grid (thresholds/tilts trained) vs the plant's own thresholds and tilts (oracle) vs wider grids.
Fitted on the first 70 %, scored on the last 30 % (RMSE / noise SD).  python oracle_grid.py SEED [CELL]"""
import json, sys, time
import numpy as np
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
hy = r["truth"]["hysteresis"]
top = float(x[:h0].max()); lo = float(x[:h0].min())
w = np.zeros(len(x)); w[:h0] = 1.0
sign = 1 if r["truth"]["sensor"]["orientation"] == "displacement" else -1

def score(name, m, **kw):
    t0 = time.time()
    res = sj.fit(m, [(x, y, dt)], weights=[w], **kw)
    e = np.asarray(sj.simulate(res.model, x, dt)) - y
    print(json.dumps(dict(seed=seed, cell=cell, variant=name, train=float(np.sqrt(np.mean(e[:h0] ** 2)) / sd),
                          held=float(np.sqrt(np.mean(e[h0:] ** 2)) / sd), s=round(time.time() - t0, 1))), flush=True)
    return res.model

def eupi(n_sym, n_alpha, n_asym, r_sym=None, r_asym=None, alpha=None):
    m = sj.EUPI.from_range(lo, top, n_sym=n_sym, n_alpha=n_alpha, n_asym=n_asym, orientation=sign)
    rep = {}
    if r_sym is not None: rep["r_sym"] = jnp.asarray(r_sym)
    if r_asym is not None: rep["r_asym"] = jnp.asarray(r_asym)
    if alpha is not None: rep["alpha"] = jnp.asarray(alpha)
    import dataclasses
    return dataclasses.replace(m, **rep).with_init("fitted")

m0 = eupi(8, 4, 4)
span = float(m0.u_span); ref = float(m0.u_ref)
print("span", span, "u_ref", ref, "train x", lo, top)
#score("default grid, thresholds+tilts trained", m0, trainable=default_trainable(m0, thresholds=True, tilts=True))
#score("default grid fixed", m0)
rs = np.array(hy["r"]); al = np.array(hy["alpha"]); ns = hy["n_sym"]
# oracle: the plant's thresholds (x units -> normalised), its tilts on an asym grid holding every true pair
if ref != 0.0:
    print("note: u_ref != 0: tilts act about u_ref, not the plant's 0; oracle only approximate")
mo = eupi(ns, len(rs) - ns, len(rs) - ns, r_sym=rs[:ns] / span, r_asym=rs[ns:] / span, alpha=al[ns:])
score("oracle thresholds/tilts (fixed)", mo)
for top_r in ():
    for n in (8, 12):
        grid = np.arange(1, n + 1) * top_r / n
        m = eupi(n, 4, 4, r_sym=grid, r_asym=np.arange(1, 5) * top_r / 4)
        score(f"grid to {top_r} x{n}, trained", m, trainable=default_trainable(m, thresholds=True, tilts=True))
# oracle memory: the plant's initial fractions on the true operators (asym grid diagonal = the true pairs)
import dataclasses
na = len(rs) - ns
fr = np.array(hy["memory"]["fractions"])
logit = lambda p: np.log(np.clip(p, 1e-6, 1 - 1e-6) / (1 - np.clip(p, 1e-6, 1 - 1e-6)))
mem = np.full(ns + na * na, 5.0)
mem[:ns] = logit(fr[:ns])
for i in range(na):
    mem[ns + i * na + i] = logit(fr[ns + i])
if hy["memory"]["kind"] == "random":
    mm = dataclasses.replace(mo, memory=jnp.asarray(mem))
    spec = default_trainable(mm)
    score("oracle thresholds/tilts + memory start", mm)
    import equinox as eqx; spec_nomem = eqx.tree_at(lambda s: s.memory, spec, False)
    score("oracle thresholds/tilts + memory fixed", mm, trainable=spec_nomem)
for L in (0.0, -5.0):
    score(f"oracle thresholds/tilts, memory start logit {L}", mo.with_fitted_memory(L))
