# python .notes/session44/truth_r03.py: plant C r03 with the true plant in the toolkit form (rules, the rested state as a fitted memory), refined from itself
"""r03 (plant C): the true plant in the toolkit's form; refine from it; from grid starts."""
import sys, json, time, dataclasses
import numpy as np
sys.path.insert(0, "/work/main/experiments")
import indep_plant_c as pc
import smafl_jax as sj
import jax.numpy as jnp
from smafl_jax.identify import default_trainable

args = (13, 131, "steps", 5, 20, "displacement", "cold", 0, None)
t, U, meas, clean, meta = pc.make_record(*args)
p = meta["plant"]; sd = meta["noise_sd"]; dt = 1 / 5
n70 = int(0.7 * len(t))
print("sees", p["sees"], "r", np.round(p["r"], 3), "alpha", np.round(p["alpha"], 3), "w", np.round(p["w"], 3), "tau", p["tau"], "sd", sd)
span = float(U[:n70].max())
r = np.array(p["r"]) / span; a = np.array(p["alpha"])
cl = a == 1.0
def truth(init="descended", memory=None):
    e = sj.EUPI.from_range(0.0, span, n_sym=int(cl.sum()), n_alpha=int((~cl).sum()), n_asym=int((~cl).sum()), poly_order=4)
    e = dataclasses.replace(e, r_sym=jnp.asarray(r[cl]), r_asym=jnp.asarray(r[~cl]), alpha=jnp.asarray(a[~cl]))
    return e
th = sj.JouleThermal(k1=jnp.asarray(p["k1"]), k2=jnp.asarray(p["k1"]), init="ambient")
rm = lambda e: float(np.sqrt(np.mean(np.square(e)))) / sd
for init in ("descended", "zero", "from_top"):
    e = dataclasses.replace(truth(), init=init)
    m = sj.Cascade(thermal=th, hysteresis=e)
    F = np.asarray(m.features(jnp.asarray(U), dt))
    # diagonal tilt grid: keep only diagonal w columns
    th_, *_ = np.linalg.lstsq(F[:n70], meas[:n70], rcond=None)
    y = F @ th_
    print(init, "train", rm(y[:n70]-meas[:n70]), "held", rm(y[n70:]-meas[n70:]), "held clean", rm(y[n70:]-clean[n70:]))
# rested: fitted memory at a*r at the first (heated) sample
m0 = sj.Cascade(thermal=th, hysteresis=truth())
x0 = float(m0.hysteresis_input(jnp.asarray(U), dt)[0]); s0 = x0 / span
print("x0", x0, "s0", s0)
rr, aa = [np.asarray(z) for z in truth()._bank()]
lo, up = s0 - rr, aa * (s0 + rr)
tgt = np.clip(aa * rr, lo, up)
f = np.clip((tgt - lo) / (up - lo), 1e-6, 1 - 1e-6)
e = truth().with_memory_fractions(f)
m = sj.Cascade(thermal=th, hysteresis=e)
F = np.asarray(m.features(jnp.asarray(U), dt))
th_, *_ = np.linalg.lstsq(F[:n70], meas[:n70], rcond=None)
y = F @ th_
print("rested(fitted mem)", "train", rm(y[:n70]-meas[:n70]), "held", rm(y[n70:]-meas[n70:]), "held clean", rm(y[n70:]-clean[n70:]), "frac", f)

# refine from the truth (rested via fitted memory), thresholds + tilts + memory + k1 + gains
m_t = m.with_hysteresis(m.hysteresis.with_linear_weights(jnp.asarray(th_))) if hasattr(m, "with_hysteresis") else m
spec = default_trainable(m_t, thresholds=True, tilts=True)
t0 = time.time()
res = sj.fit(m_t, (U[:n70], meas[:n70]), dt, trainable=spec, init=None)
mf = res.model
y = np.asarray(sj.simulate(mf, jnp.asarray(U), dt))
print("refined from truth", "train", rm(y[:n70]-meas[:n70]), "held", rm(y[n70:]-meas[n70:]), "held clean", rm(y[n70:]-clean[n70:]), f"{time.time()-t0:.1f}s")
print("k1", float(mf.thermal.k1), "true", p["k1"], "r", np.asarray(mf.hysteresis._bank()[0]) * span, "a", np.asarray(mf.hysteresis._bank()[1]))
