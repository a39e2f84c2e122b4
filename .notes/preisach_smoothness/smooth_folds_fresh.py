import json, sys, os, glob
import numpy as np
import smafl_jax as sj
from smafl_jax.identify._fit import _features, _linear_part  # private: probe
from smafl_jax.identify import _gain_prior as g  # private: probe
from smafl_jax.identify.linear import solve
done = set()
if os.path.exists(sys.argv[1]):
    done = {json.loads(l)["name"] for l in open(sys.argv[1])}
out_f = open(sys.argv[1], "a")
for fj in sorted(glob.glob("/tmp/cf_work/*/fit_P/fit.json")):
    d = os.path.dirname(os.path.dirname(fj)); n = os.path.basename(d)
    if n in done: continue
    z = np.load(os.path.join(d, "full.npz")); h0 = int(z["h0"]); sd = float(z["sd"])
    m = sj.load_model(fj); h = sj.hysteresis_of(m)
    feats, nonneg, _ = _linear_part(m)
    A = np.asarray(_features(feats, m, np.asarray(z["u"]), float(z["dt"]))); y = np.asarray(z["y"])
    At, yt = A[:h0], y[:h0]
    free = solve(At, yt, nonneg, **g.FIT_SOLVE); sig2 = 2 * free.loss / h0
    prior = np.diag(np.where(nonneg, sig2 / np.ptp(yt) ** 2, 0.0)); sm = h.weight_smoothness()
    blocks = np.array_split(np.arange(h0), 5)
    out = {"name": n, "folds": {}, "held": {}}
    saved = float(np.sqrt(np.mean((np.asarray(sj.simulate(m, z["u"], float(z["dt"])))[h0:] - y[h0:]) ** 2)) / sd)
    out["saved"] = saved
    for lam in g.SMOOTH_STRENGTHS:
        f = []
        for held in blocks[1:]:
            keep = np.ones(h0, bool); keep[held] = False
            x = solve(At[keep], yt[keep], nonneg, penalty=prior + lam * keep.sum() * sm, **g._solve_options(lam)).x
            r = At[held] @ x - yt[held]; f.append(float(r @ r))
        x = solve(At, yt, nonneg, penalty=prior + lam * h0 * sm, **g._solve_options(lam)).x
        out["folds"][lam] = f; out["held"][lam] = float(np.sqrt(np.mean((A[h0:] @ x - y[h0:]) ** 2)) / sd)
    out_f.write(json.dumps(out) + "\n"); out_f.flush()
