"""Refit a random cell's 70 % with fit_record defaults; print the error over time and save a plot."""
import sys, json
import numpy as np
import smafl_jax as sj
from smafl_jax.report import fit_record
import matplotlib; matplotlib.use("Agg"); import matplotlib.pyplot as plt
full, part, out = sys.argv[1], sys.argv[2], sys.argv[3]
truth = json.load(open(full.replace(".csv", ".truth.json")))
rec, p70 = sj.load_record(full), sj.load_record(part)
model, doc, _ = fit_record(p70)
yh = np.asarray(sj.simulate(model, rec.u, rec.dt))
e = yh - rec.y
h0 = truth["heldout_start"]; sd = truth["noise_sd"]
n = len(e); blocks = np.array_split(np.arange(n), 20)
print("block rms/noise:", " ".join(f"{np.sqrt(np.mean(e[b]**2))/sd:.1f}" for b in blocks), "| h0 block", h0 * 20 // n)
print("mean err held", e[h0:].mean() / sd, "std", e[h0:].std() / sd)
print("u range train", rec.u[:h0].min(), rec.u[:h0].max(), "held", rec.u[h0:].min(), rec.u[h0:].max())
fig, ax = plt.subplots(3, 1, figsize=(12, 8), sharex=True)
t = rec.time
ax[0].plot(t, rec.u, lw=0.4); ax[0].set_ylabel("u")
ax[1].plot(t, rec.y, lw=0.4, label="measured"); ax[1].plot(t, yh, lw=0.4, label="model"); ax[1].legend()
ax[2].plot(t, e / sd, lw=0.4); ax[2].set_ylabel("err / noise"); ax[2].axvline(t[h0], color="k")
fig.savefig(out, dpi=80)
