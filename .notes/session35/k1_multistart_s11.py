"""Multi-start of the joint refinement over k1 from a fitted 70% model."""
import sys, numpy as np, json, time
import equinox as eqx, jax.numpy as jnp
import smafl_jax as sj
from smafl_jax.identify._fit import default_trainable  # private: probe
tag = sys.argv[1]; mname = sys.argv[2]
d = np.load(f"/tmp/s35_{tag}.npz"); h0 = int(d["h0"])
rec = sj.load_record(f"/tmp/s35_{tag}.csv"); r70 = sj.load_record(f"/tmp/s35_{tag}_70.csv")
m0 = sj.load_model(mname)
def score(m):
    yh = np.asarray(sj.simulate(m, rec.u, rec.dt)); e = yh - rec.y
    return np.sqrt(np.mean(e[:h0]**2))/0.005, np.sqrt(np.mean(e[h0:]**2))/0.005
print("base", score(m0), float(m0.thermal.k1))
for f in (0.8, 0.9, 0.95, 1.0, 1.05, 1.1, 1.25):
    t0 = time.time()
    m = eqx.tree_at(lambda m: m.thermal.k1, m0, jnp.asarray(float(m0.thermal.k1) * f))
    m = sj.fit(m, r70, solver=None, init="linear", gain_prior=1.0).model
    spec = default_trainable(m, thresholds=True, tilts=True)
    res = sj.fit(m, r70, trainable=spec, init=None, gain_prior=1.0)
    print(f, "k1 %.4f -> %.4f" % (float(m0.thermal.k1)*f, float(res.model.thermal.k1)), "loss %.5g" % res.loss, "train/held %.3f %.3f" % score(res.model), "%.0f s" % (time.time()-t0), res.n_steps)
