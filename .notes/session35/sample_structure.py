"""Probe: does sampling the thresholds and tilts too (marginalised gains) fix the held-out coverage of records whose
95 % bands covered ~0 % (experiments/heldout_coverage.py)?  Usage: sample_structure.py RECORD_DIR STEPS [structure]"""
import sys, time, numpy as np
import smafl_jax as sj
from smafl_jax.identify._fit import default_trainable  # private: probe
D, steps = sys.argv[1], int(sys.argv[2])
structure = len(sys.argv) > 3
model, doc = sj.load_model_file(f"{D}/fit/fit.json")
rec = sj.load_record(f"{D}/record.csv"); n = len(sj.load_record(f"{D}/train70.csv"))
spec = default_trainable(model, thresholds=structure, tilts=structure)
# the sampler's default trainable includes the fitted memory; keep it, add thresholds/tilts
post = sj.Posterior(model, (rec.u[:n], rec.y[:n]), rec.dt, linear="marginalise",
                    trainable=spec if structure else None)
print("ndim", post.ndim, post.names_leaf, flush=True)
t0 = time.time()
run = sj.run_sampler(post, steps, path=None, progress=False)
burn = steps // 2
flat = run.chain[burn:].reshape(-1, post.ndim)
rng = np.random.default_rng(1)
idx = rng.choice(flat.shape[0], size=200, replace=False)
f, yrep = post.predict(flat[idx], rec.u, rec.dt, rng)
q = np.quantile(yrep, [0.025, 0.975], axis=0); med = np.median(f, 0)
h = np.arange(len(rec)) >= n
sd = 0.005
print(f"structure={structure} steps={steps} {time.time()-t0:.0f} s: held-out coverage {np.mean((rec.y[h] >= q[0][h]) & (rec.y[h] <= q[1][h])):.3f}, "
      f"median RMSE {np.sqrt(np.mean((med[h]-rec.y[h])**2))/sd:.2f}x, band half-width {np.median(q[1][h]-q[0][h])/2/sd:.2f}x; "
      f"acceptance {np.mean(run.acceptance_fraction):.2f}", flush=True)
