"""Session 63: the delay candidate on independent record delay s7006 (fractional output delay 2.90 s): the diagnosis'
own fit vs one started at the true delay, against sensor_lag.  python delay_probe.py [TRUTH SEED]"""
import sys, tempfile
import numpy as np
import jax.numpy as jnp
sys.path.insert(0, "experiments")
import indep_effects as ie
from smafl_jax.diagnosis import _diagnose as D
from smafl_jax.effects import ExtendedModel
from smafl_jax.effects.catalogue import Delay

truth, seed = (sys.argv[1], int(sys.argv[2])) if len(sys.argv) > 2 else ("delay", 7006)
with tempfile.TemporaryDirectory() as tmp:
    rec, case, split, screened, base = ie.diagnosis_start(tmp, truth, seed)
noise = case["noise_rms_measured"]
print(case["effect_params"], "dt", 1 / case["rate_hz"])
h = lambda m: D._held(m, split)["rmse"] / noise
t = lambda m: np.sqrt(D._train_sse(m, split.train) / sum(s.mask.sum() for s in split.train)) / noise
print(f"base: train {t(base):.3f} held {h(base):.3f}")
for name in ("delay", "sensor_lag"):
    m, info = D.fit_extended(base, [name], split)
    print(f"{name}: train {t(m):.3f} held {h(m):.3f} params {[(k, float(v)) for k, v in vars(m.get(name)).items() if hasattr(v, 'shape')]}")
tau = case["effect_params"]["delay_s"] + case["effect_params"].get("fraction", 0) / case["rate_hz"]
for tt in (case["effect_params"]["delay_s"], tau):
    st = ExtendedModel(ExtendedModel.of(base).base, (Delay(tau=jnp.asarray(tt)),))
    m0, _ = D.profile_gains(st, split.train)
    m, _ = D.fit_extended(st, ["delay"], split)
    print(f"delay at {tt:.3f} s: profiled train {t(m0):.3f} held {h(m0):.3f}; refit train {t(m):.3f} held {h(m):.3f} tau {float(m.get('delay').tau):.3f}")

print("--- with the diagnosis' refinement")
rb, cs, _ = D.refined_base(base, screened, split)
rb, _ = D.converged_base(rb, split)
print(f"refined base: train {t(rb):.3f} held {h(rb):.3f}; cand_start train {t(cs):.3f} held {h(cs):.3f}")
for name in ("delay", "sensor_lag"):
    m, info = D.fit_extended(cs, [name], split)
    r = D.refine_model(m, split)
    print(f"{name} from cand_start: VP train {t(m):.3f} held {h(m):.3f} -> refined train {t(r):.3f} held {h(r):.3f} (refined kept: {r is not m}) tau {float(r.get(name).tau):.3f}")
    m2, _ = D.fit_extended(rb, [name], split)
    r2 = D.refine_model(m2, split)
    print(f"{name} from refined base: VP train {t(m2):.3f} held {h(m2):.3f} -> refined train {t(r2):.3f} held {h(r2):.3f} (refined kept: {r2 is not m2}) tau {float(r2.get(name).tau):.3f}")
