"""Exact (grid) posterior of the cascade's k1 (gains marginalised, sigma integrated on a grid) with
the package's own Posterior density: physical log density = log_prob(raw) - log_jacobian(raw)."""
import sys, json, math
from pathlib import Path
import numpy as np
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "experiments")); sys.path.insert(0, str(Path(__file__).parent))
import calibration as cal
import smafl_jax as sj
from exact_grid import quantiles

def sp_inv(x): return np.log(np.expm1(x))
def log_sig(r): return -np.logaddexp(0.0, -r)

def phys_lp(post, k1, s):
    raw = sp_inv(np.column_stack([k1, s]))
    out = np.empty(len(raw))
    for i in range(0, len(raw), 4096):
        out[i:i+4096] = post(raw[i:i+4096])
    return out - log_sig(raw).sum(1)

def analyse(r, seed=0):
    rng = np.random.default_rng([seed, 1000 + r])
    u, y, dt = cal.cascade_record(rng)
    template = cal.cascade_truth()
    start = sj.Cascade(thermal=sj.JouleThermal(), hysteresis=template.hysteresis)
    post = sj.Posterior(start, (u, y), dt, linear="marginalise", sigma=0.02)
    k1c = np.geomspace(0.03, 0.2, 600)
    lp = phys_lp(post, k1c, np.full_like(k1c, 0.01)); w = np.exp(lp - lp.max())
    m = (k1c * w).sum() / w.sum(); sd = math.sqrt(((k1c - m) ** 2 * w).sum() / w.sum())
    k1g = np.linspace(max(m - 10 * sd, 1e-3), m + 12 * sd, 301)
    sg = np.geomspace(0.0065, 0.0155, 60)
    K, S = np.meshgrid(k1g, sg, indexing="ij")
    lp = phys_lp(post, K.ravel(), S.ravel()).reshape(K.shape)
    P = np.exp(lp - lp.max()) * sg[None, :]  # d sigma = sigma d log sigma
    w1 = P.sum(1)
    edge = (w1[0] + w1[-1]) / w1.sum(); sedge = (P[:, 0].sum() + P[:, -1].sum()) / P.sum()
    q = quantiles(k1g, w1, [0.025, 0.05, 0.5, 0.95, 0.975])
    mean = (k1g * w1).sum() / w1.sum(); sdk = math.sqrt(((k1g - mean) ** 2 * w1).sum() / w1.sum())
    return dict(r=r, q=q.tolist(), mean=mean, z=(mean - cal.K1) / sdk, edge=edge, sedge=sedge)

if __name__ == "__main__":
    seed, r0, n = map(int, sys.argv[1:4])
    res = []
    for r in range(r0, r0 + n):
        res.append(analyse(r, seed)); print(r, res[-1]["q"][1], res[-1]["q"][3], file=sys.stderr)
    json.dump(res, open(f"/tmp/casc_{seed}_{r0}_{n}.json", "w"))
    K = cal.K1
    h90 = np.array([x["q"][1] <= K <= x["q"][3] for x in res]); h95 = np.array([x["q"][0] <= K <= x["q"][4] for x in res])
    z = np.array([x["z"] for x in res])
    print(f"cascade k1 grid: n={n} cov90 {100*h90.mean():.1f} (+-{100*math.sqrt(.09/n):.1f}) cov95 {100*h95.mean():.1f}  z mean {z.mean():+.3f} sd {z.std(ddof=1):.3f}  max edge {max(x['edge'] for x in res):.1e} / {max(x['sedge'] for x in res):.1e}")
