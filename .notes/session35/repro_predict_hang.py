"""Standalone: Posterior.predict with 200 draws on a 7500-sample record (batches of 133)."""
import sys, faulthandler, time
sys.path.insert(0, sys.argv[1])
faulthandler.dump_traceback_later(int(sys.argv[2]), exit=True)
import numpy as np, smafl_jax as sj
D = "/tmp/hcA/s13_multisine_cold_displacement_25hz"
model, _ = sj.load_model_file(f"{D}/fit/fit.json")
rec = sj.load_record(f"{D}/record.csv")
n = 5250
post = sj.Posterior(model, (rec.u[:n], rec.y[:n]), rec.dt, linear="marginalise", gain_scale=0.5657434958)
rng = np.random.default_rng(0)
th = post.theta0 + 0.01 * rng.standard_normal((200, post.ndim))
t0 = time.time()
f, y = post.predict(th, rec.u, rec.dt, rng)
print("ok", time.time() - t0, np.isfinite(f).all(), sj.__file__)
