"""Session 71 probe: does the delay candidate's fit find the plant's delay on blind record delay s7011 (3.83 s)?"""
import sys, time, tempfile
import numpy as np
sys.path.insert(0, "experiments")
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D  # private: probe of the candidate fit
from smafl_jax.effects import ExtendedModel
from smafl_jax.effects.catalogue import Delay
import jax.numpy as jnp

seed = int(sys.argv[1]); kind = sys.argv[2]
path, case = ie.write_effect_record(tempfile.mkdtemp(), "delay", seed)
print(case["effect_params"], case["drive"], case["n"])
rec = sj.load_record(path)
base0, _ = D.choose_base(rec)
split = D.make_split(rec, kind=kind)
print("split", split.kind)
t = time.time()
base0, scr = D.screened_base(base0, split, False)
base, info = D.fit_extended(base0, [], split)
base, cand_start, _ = D.refined_base(base, base0, split, False)
base, _ = D.converged_base(base, split, False)
btr, bte = D._metrics_pair(base, split)
print(f"base train {btr['rmse']:.5f} held {bte['rmse']:.5f}  ({time.time()-t:.0f} s)")
ctx = D._context(split)
for st in D._effect_grid("delay", ctx):
    m = ExtendedModel(cand_start.base if isinstance(cand_start, ExtendedModel) else cand_start, (st,))
    _, sse = D.profile_gains(m, split.train)
    print(f"  grid tau {float(st.tau):.3f}: train sse {sse:.5g}")
m, info = D.fit_extended(cand_start, ["delay"], split)
tr, te = D._metrics_pair(m, split)
print(f"fit delay: tau {float(m.get('delay').tau):.3f} train {tr['rmse']:.5f} held {te['rmse']:.5f} k1 {float(D.thermal_of(m).k1):.4g} (base k1 {float(D.thermal_of(cand_start).k1):.4g})")
b = cand_start.base if isinstance(cand_start, ExtendedModel) else cand_start
for tau in (case["effect_params"]["delay_s"], 0.5 * case["effect_params"]["delay_s"]):
    m2, info2 = D.fit_extended(ExtendedModel(b, (Delay(tau=jnp.asarray(tau)),)), [], split)
    tr2, te2 = D._metrics_pair(m2, split)
    print(f"from tau {tau:.3f}: tau {float(m2.get('delay').tau):.3f} train {tr2['rmse']:.5f} held {te2['rmse']:.5f} k1 {float(D.thermal_of(m2).k1):.4g}")
