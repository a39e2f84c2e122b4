"""Exact (grid) posterior of (k1, k2) for the joule calibration study; sigma integrated out.

Model is linear in k2 for fixed k1: theta = k2 * h(k1). Priors: the package defaults (lognormal on
k1, k2 in physical space; half-normal sigma with scale = output range, ~flat at sigma~0.05 so the
sigma integral is done numerically on a log grid including the prior).
"""
import sys, json, math
from pathlib import Path
import numpy as np
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "experiments"))
import calibration as cal

K1, K2 = cal.K1, cal.K2

def h_of(k1, u, dt):
    a = np.exp(-k1 * dt)              # (G,)
    g = 1.0 / k1
    th = g * u[0] ** 2 * np.ones_like(k1)
    out = np.empty((len(u), len(k1)))
    for k, x in enumerate(u):
        th = a * th + (1 - a) * g * x * x
        out[k] = th
    return out                         # (n, G)

def lognorm_logpdf(x, loc, scale):
    lx = np.log(x); return -0.5 * ((lx - loc) / scale) ** 2 - lx

def grid_post(u, y, dt, half=8.0, G1=801, G2=801):
    yr = float(np.ptp(y)); umax = float(np.max(np.abs(u)))
    # locate the mode roughly from a coarse k1 scan (k2 profiled)
    k1c = np.linspace(0.055, 0.070, 301)
    H = h_of(k1c, u, dt)
    k2hat = (H * y[:, None]).sum(0) / (H * H).sum(0)
    ssr = ((y[:, None] - H * k2hat) ** 2).sum(0)
    i = np.argmin(ssr); k1m = k1c[i]
    # curvature-based sd of k1 from profile ssr: sd ~ sigma/sqrt(d2/2)
    s2 = ssr[i] / (len(y) - 2)
    d2 = (ssr[i + 1] - 2 * ssr[i] + ssr[i - 1]) / (k1c[1] - k1c[0]) ** 2
    sd1 = math.sqrt(2 * s2 / d2)
    k1g = np.linspace(k1m - half * sd1, k1m + half * sd1, G1)
    H = h_of(k1g, u, dt)
    hh = (H * H).sum(0); hy = (H * y[:, None]).sum(0); yy = y @ y
    k2hat = hy / hh; sd2 = math.sqrt(s2 / hh[G1 // 2])
    # k2 conditional spread is sqrt(s2/hh); k2hat varies with k1 -> grid wide enough for all
    k2g = np.linspace(k2hat.min() - half * sd2, k2hat.max() + half * sd2, G2)
    SSR = yy - 2 * np.outer(hy, k2g) + np.outer(hh, k2g ** 2)  # (G1, G2)
    n = len(y)
    sg = np.geomspace(0.2 * math.sqrt(s2), 5 * math.sqrt(s2), 400)
    dls = np.log(sg[1] / sg[0])
    # integrate sigma: sum over log-grid of p(sigma) * L * sigma (d sigma = sigma dlog)
    lp_s = -0.5 * (sg / yr) ** 2  # halfnormal up to const
    # chunk over sigma to bound memory
    acc = None
    for s, lps in zip(sg, lp_s):
        t = -0.5 * SSR / s**2 - n * math.log(s) + lps + math.log(s) + math.log(dls)
        acc = t if acc is None else np.logaddexp(acc, t)
    lpost = acc + lognorm_logpdf(k1g, math.log(0.05), 2.0)[:, None] + lognorm_logpdf(k2g, math.log(0.05 * yr / umax**2), 3.0)[None, :]
    P = np.exp(lpost - lpost.max())
    # edge mass check
    edge = (P[0].sum() + P[-1].sum() + P[:, 0].sum() + P[:, -1].sum()) / P.sum()
    return k1g, k2g, P, edge

def quantiles(x, w, qs):
    c = np.cumsum(w); c = c / c[-1]
    # midpoint cdf for a fine uniform grid
    c = c - 0.5 * w / w.sum()
    return np.interp(qs, c, x)

def analyse(r, seed=0):
    rng = np.random.default_rng([seed, r])
    u, y, dt = cal.joule_record(rng)
    k1g, k2g, P, edge = grid_post(u, y, dt)
    q = [0.025, 0.05, 0.5, 0.95, 0.975]
    q1 = quantiles(k1g, P.sum(1), q); q2 = quantiles(k2g, P.sum(0), q)
    m1 = (k1g * P.sum(1)).sum() / P.sum(); m2 = (k2g * P.sum(0)).sum() / P.sum()
    return dict(r=r, k1=q1.tolist(), k2=q2.tolist(), edge=edge, m1=m1, m2=m2)

if __name__ == "__main__":
    n = int(sys.argv[1]); seed = int(sys.argv[2]) if len(sys.argv) > 2 else 0
    res = [analyse(r, seed) for r in range(n)]
    json.dump(res, open(f"/tmp/grid_{seed}_{n}.json", "w"))
    for nm, K in (("k1", K1), ("k2", K2)):
        h90 = np.mean([x[nm][1] <= K <= x[nm][3] for x in res]); h95 = np.mean([x[nm][0] <= K <= x[nm][4] for x in res])
        print(f"{nm}: exact-grid coverage over {n} reps: 90% {100*h90:.1f}  95% {100*h95:.1f}")
    print("max edge mass", max(x["edge"] for x in res))
