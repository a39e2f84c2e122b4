"""Anchored re-profiling: gains solved as base gains + delta, the delta ridge-pinned in poorly determined directions.
python anchored.py PKL [RIDGE ...]"""
import sys, pickle
import numpy as np
from smafl_jax.diagnosis import _diagnose as D
from smafl_jax.identify.linear import solve
g = pickle.load(open(sys.argv[1], "rb"))
ridges = [r if r == 'auto' else float(r) for r in sys.argv[2:]] or [0.0, 1e-10, 1e-8, 1e-6]
base, start, split, name, case = g["base"], g["start"], g["split"], g["name"], g["case"]
noise = case["noise_rms_measured"]
print(g["truth"], g["seed"], name, {k: case[k] for k in ("drive", "rate_hz", "minutes", "start", "variant", "effect_over_noise")})
def rep(lab, m):
    tr, te = D._metrics_pair(m, split)
    print(f"  {lab:40s} train {tr['rmse']/noise:6.2f} held {te['rmse']/noise:6.2f}", flush=True)
    return te['rmse'] / noise
rep("base (diagnose)", base)
rep("joint (diagnose)", g["joint"])
rep("base BVLS re-profiled", D.profile_gains(base, split.train)[0])
orig = D._bvls
ST = {}
def anchored(A, b, nonneg):
    th = np.asarray(ST["anchor"], float)
    th = np.r_[th, np.zeros(A.shape[1] - len(th))]
    lo = np.where(nonneg, -th, -np.inf)
    d = solve(A, b - A @ th, None, lower=lo, ridge=ST["ridge"], clip=False).x
    return th + d
D._bvls = anchored
ytr = np.concatenate([s.y[s.mask] for s in split.train])
tr_rmse = D._metrics_pair(base, split)[0]['rmse']
auto = (tr_rmse / np.ptp(ytr)) ** 2 / len(ytr)
print("  auto ridge %.3g (train rmse %.4g, range %.4g, n %d)" % (auto, tr_rmse, np.ptp(ytr), len(ytr)))
for r in ridges:
    r = auto if r == 'auto' else r
    ST["ridge"] = r
    ST["anchor"] = np.asarray(base.hysteresis.linear_weights())
    print(f" ridge {r:g}")
    hb = rep("base anchored re-profiled", D.profile_gains(base, split.train)[0])
    m = D.fit_extended(base, [name], split)[0]
    h1 = rep(f"{name} anchored varpro", m)
    mr = D.refine_model(m, split)
    h2 = rep(f"{name} anchored then refined", mr)
    print("   effect", D._effect_params(mr.get(name)), " gain vs anchored base %.2f" % (1 - h2 / hb))
D._bvls = orig
