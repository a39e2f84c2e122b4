import json, sys, os
import numpy as np
import smafl_jax as sj
from smafl_jax.identify._fit import _features, _linear_part  # private: probe
from smafl_jax.identify import _gain_prior as g  # private: probe
from smafl_jax.identify.linear import solve
exec(open("/tmp/s21/fold_choice.py").read().split("rows = []")[0])
only = sys.argv[1:]
for n in eupi:
    if n not in pre or (only and not any(o in n for o in only)): continue
    fj = path(pre[n]); d = os.path.dirname(os.path.dirname(fj)); sd = float(n.split("_n")[-1])
    m = sj.load_model(fj); h = sj.hysteresis_of(m)
    fp = os.path.join(d, "full.csv"); full = sj.load_record(fp if os.path.exists(fp) else f"/tmp/plant_b_fits/{n}/full.csv")
    h0 = len(sj.load_record(os.path.join(d, "first70.csv")).u)
    feats, nonneg, _ = _linear_part(m)
    A = np.asarray(_features(feats, m, np.asarray(full.u), full.dt)); y = np.asarray(full.y)
    At, yt = A[:h0], y[:h0]
    free = solve(At, yt, nonneg, **g.FIT_SOLVE); sig2 = 2 * free.loss / h0
    prior = np.diag(np.where(nonneg, sig2 / np.ptp(yt) ** 2, 0.0)); sm = h.weight_smoothness()
    blocks = np.array_split(np.arange(h0), 5)
    out = {"name": n, "folds": {}, "held": {}}
    for lam in g.SMOOTH_STRENGTHS:
        f = []
        for held in blocks[1:]:
            keep = np.ones(h0, bool); keep[held] = False
            x = solve(At[keep], yt[keep], nonneg, penalty=prior + lam * keep.sum() * sm, **g._solve_options(lam)).x
            r = At[held] @ x - yt[held]; f.append(float(r @ r))
        x = solve(At, yt, nonneg, penalty=prior + lam * h0 * sm, **g._solve_options(lam)).x
        out["folds"][lam] = f; out["held"][lam] = float(np.sqrt(np.mean((A[h0:] @ x - y[h0:]) ** 2)) / sd)
    print(json.dumps(out), flush=True)
