import sys
import numpy as np
sys.path[:0] = ["/work/main", "/work/main/experiments"]
import indep_effects as ie
import smafl_jax as sj
import jax.numpy as jnp
from smafl_jax.diagnosis import diagnose
from smafl_jax.diagnosis._diagnose import profile_gains, _held  # private: probe
from smafl_jax.effects import ExtendedModel, Delay
path, case = ie.write_effect_record("/tmp/s25_probe", "delay", 7001)
rec = sj.load_record(path)
d = diagnose(rec, effects=["delay"], refit=False, verbose=False, n_null=2, unexplained=False)
sj.save_model("/tmp/s25_probe/delay7001_base.json", d.base)
base, split = d.base, d.split
dt = rec.dt
for s in [8, 12, 14, 15, 16, 16.5, 17, 17.5, 18, 18.3, 18.5, 19, 20, 22, 24, 32]:
    m, sse = profile_gains(ExtendedModel(base, (Delay(tau=jnp.asarray(s * dt)),)), split.train)
    print(f"{s:5.1f} samples  train sse {float(sse):.5f}  held {_held(m, split)['rmse']:.5f}")
