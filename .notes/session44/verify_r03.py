# python .notes/session44/verify_r03.py: plant C r03, the screened start refined by lm or varpro, then the operator memory searched and varpro again
import sys, time, numpy as np
sys.path.insert(0, "/work/main/experiments")
import indep_plant_c as pc, plant_c_trial as tr
import smafl_jax as sj, jax.numpy as jnp
from smafl_jax.report import fit_record
from smafl_jax.identify import default_trainable, search_memory
t, U, meas, clean, meta = pc.make_record(*tr.RECORDS["r03"]); sd = meta["noise_sd"]; n70 = int(0.7*len(t)); dt = t[1]-t[0]
rec = sj.Record.from_arrays(t[:n70], U[:n70], meas[:n70], input_name="voltage_V", output_name="displacement_mm")
rm = lambda e: float(np.sqrt(np.mean(np.square(e)))) / sd
def show(lab, m):
    y = np.asarray(sj.simulate(m, jnp.asarray(U), dt))
    print(f"{lab:50s} train {rm(y[:n70]-meas[:n70]):6.2f} held {rm(y[n70:]-meas[n70:]):6.2f}", flush=True)
m, doc, masks = fit_record(rec, model="cascade", split="none", thresholds=True, tilts=True, max_steps=0)
spec = default_trainable(m, thresholds=True, tilts=True)
show("screened start", m)
for path in ("lm", "varpro"):
    r = sj.fit(m, rec, trainable=spec, init=None, solver=path)
    show(f"{path} from the screened start ({r.n_steps} steps)", r.model)
    f0 = r.model.with_hysteresis(r.model.hysteresis.with_fitted_memory())
    got = search_memory(f0, ((U[:n70], meas[:n70], dt),), (np.ones(n70),))
    if got:
        show(f"  + memory search", got[0])
        r2 = sj.fit(got[0], rec, trainable=default_trainable(got[0], thresholds=True, tilts=True), init=None, solver="varpro")
        show(f"  + varpro again ({r2.n_steps} steps)", r2.model)
