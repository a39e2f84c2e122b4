import sys, numpy as np, jax.numpy as jnp, pickle
import smafl_jax as sj
from smafl_jax.identify._multi_record import _joint_fit
from smafl_jax.identify._fit import _residuals_jit
recs=[sj.load_record(f"/tmp/s33/multi/{n}.csv") for n in sys.argv[1:]]
res, info = _joint_fit(recs, model="cascade", solver="lm", max_steps=300, thresholds=None, tilts=None, grid=None, orientation="auto", thermal_start="auto", sees="auto", gain_prior=None, progress=True)
m=res.model
print(res.message, res.loss, res.init_loss, float(m.thermal.k1), m.thermal.u0)
sj.save_model("/tmp/s33/probe_j12_model.json", m)
args=tuple((jnp.asarray(r.u), jnp.asarray(r.y), jnp.asarray(r.dt), jnp.ones(len(r))) for r in recs)
for k in (0.04,0.048,0.055,0.0678,0.08):
    mk=sj.identify.init_linear(sj.identify._fit._set_k1(m,k), [(r.u,r.y,r.dt) for r in recs])
    r_=np.asarray(_residuals_jit(mk,args)); print(k, 0.5*r_@r_)
