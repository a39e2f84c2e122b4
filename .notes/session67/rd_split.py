"""Session 67: the lagged rate_dependence fitted on the diagnosis split of a captured record (held-out failure of
s5005): python rd_split.py OUT.pkl  [TAUMAX=10] [LOOK=1 error by eighth of the held-out block] [LOOK2=1 where it fails]"""
import sys, pickle, os
from smafl_jax.diagnosis import _diagnose as D
from smafl_jax.effects.catalogue import RateDependence as RD
if os.environ.get("TAUMAX"): RD.TAU_MAX = float(os.environ["TAUMAX"])
g = pickle.load(open(sys.argv[1], "rb"))
split, base, start = g["split"], g["base"], g["start"]
sd = g["case"]["noise_sd"]
m, info = D.fit_extended(start, ["rate_dependence"], split)
m0 = m
m = D.refine_model(m, split)
m, info = D._from_refined_base_too(m, info, base, start, "rate_dependence", split)
tr, te = D._metrics_pair(m, split)
btr, bte = D._metrics_pair(base, split)
e = m.get("rate_dependence"); e0 = m0.get("rate_dependence")
print(sys.argv[1].split("/")[-1], f"TAUMAX {RD.TAU_MAX}: base train {btr['rmse']/sd:.2f} held {bte['rmse']/sd:.2f} | rd train {tr['rmse']/sd:.2f} held {te['rmse']/sd:.2f} c {float(e.c):.3g} tau {float(e.tau):.3g} (vp c {float(e0.c):.3g} tau {float(e0.tau):.3g})")
import numpy as np, jax.numpy as jnp
if os.environ.get("LOOK"):
    for nm_, mm in (("base", base), ("rd", m)):
        for s_ in split.test:
            y = np.asarray(D.simulate_segment(mm, s_)); err = (y - np.asarray(s_.y))[s_.mask] if hasattr(s_, "mask") else y - np.asarray(s_.y)
            n = len(err); q = n // 8
            print(nm_, "held-out err RMS by eighth:", " ".join(f"{np.sqrt(np.mean(err[i*q:(i+1)*q]**2))/sd:.1f}" for i in range(8)))
    x = m.hysteresis_input(jnp.asarray(split.test[0].u), jnp.asarray(split.test[0].dt))
    f = np.asarray(e.threshold_scale(x, split.test[0].dt, m.hysteresis))
    xt = m.hysteresis_input(jnp.asarray(split.train[0].u), jnp.asarray(split.train[0].dt))
    ft = np.asarray(e.threshold_scale(xt, split.train[0].dt, m.hysteresis))
    print("scale train max/p99", ft.max(), np.percentile(ft, 99), " held max/p99", f.max(), np.percentile(f, 99))
    print("u range train", float(np.min(split.train[0].u)), float(np.max(split.train[0].u)), "held", float(np.min(split.test[0].u)), float(np.max(split.test[0].u)))
if os.environ.get("LOOK2"):
    s_ = split.test[0]
    yb = np.asarray(D.simulate_segment(base, s_)); yr = np.asarray(D.simulate_segment(m, s_)); yy = np.asarray(s_.y)
    er = np.abs(yr - yy) / sd
    k = int(np.argmax(er > 5))
    u = np.asarray(s_.u); x = np.asarray(m.hysteresis_input(jnp.asarray(u), jnp.asarray(s_.dt)))
    f = np.asarray(e.threshold_scale(jnp.asarray(x), s_.dt, m.hysteresis))
    print("first |err|>5 at", k, "of", len(er), "dt", s_.dt)
    for j in range(max(0, k - 40), min(len(er), k + 30), 5):
        print(j, f"u {u[j]:.2f} x {x[j]:.3f} scale {f[j]:.2f} y {yy[j]:.3f} rd {yr[j]:.3f} base {yb[j]:.3f}")
