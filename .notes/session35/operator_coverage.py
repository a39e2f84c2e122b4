import sys, json; sys.path.insert(0, "tests")
import numpy as np, indep_plant as ip, copy
from smafl_jax.ops import play
res = {(r["seed"], r["cell"]): r["held"] for r in json.load(open("experiments/results/base_fit_matrix_session32.json"))}
def cov(x, h0, widths, tol=0.02):
    span = np.ptp(x[:h0]) or 1.0
    lo = x[:h0].min()
    P = np.asarray(play(x, np.asarray(widths*span), y0=np.full(len(widths), x[0]), method="scan"))
    bad = np.zeros(len(x) - h0, bool)
    worst = []
    for j in range(len(widths)):
        p = P[:, j]; s = np.sign(np.diff(p, prepend=p[0]))
        cells = np.floor((p - lo)/(tol*span)).astype(int)
        for k in (1, -1):
            seen = set(cells[:h0][s[:h0] == k].tolist())
            ok = np.array([(c in seen) or (c-1 in seen) or (c+1 in seen) for c in cells[h0:]])
            m = (s[h0:] == k) & ~ok
            bad |= m
        worst.append(round(float(np.mean(bad)), 2))
    return float(np.mean(bad)), worst
widths = np.array([0.01, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5])
for name, kw in ip.MATRIX_CELLS.items():
    for seed in (7, 11, 13, 17, 19):
        r = ip.make_record(seed, minutes=10, **kw)
        t = copy.deepcopy(r["truth"]); t["effect"] = None
        x = ip._core(t, r["u"], r["dt"], upto="x")["x_h"]; h0 = r["heldout_start"]
        f, w = cov(x, h0, widths)
        print(f"{name:42s} s{seed:<3d} held={res.get((seed,name), float('nan')):6.2f} uncovered={f:.2f} cum-by-width={w}")
