"""Session 63: on independent records with an uncatalogued extra-column effect, which candidate signal does the
diagnosis base's held-out residual correlate with most, with and without interaction signals (extra column x input,
x input^2, x thermal state), raw and low-passed (the unexplained report's time constants).
python extra_interaction_probe.py TRUTH:SEED [...]"""
import sys, tempfile
import numpy as np
import jax.numpy as jnp
sys.path.insert(0, "experiments")
import indep_effects as ie
from smafl_jax.diagnosis import _diagnose as D
from smafl_jax.diagnosis._residuals import candidate_signals, signal_correlations
from smafl_jax.diagnosis._unexplained import lowpass, TAU_FRACTIONS

for arg in sys.argv[1:]:
    truth, seed = arg.split(":")
    with tempfile.TemporaryDirectory() as tmp:
        rec, case, split, screened, base = ie.diagnosis_start(tmp, truth, int(seed))
    rb, cs, _ = D.refined_base(base, screened, split)
    rb, _ = D.converged_base(rb, split)
    for part, segs in (("train", split.train), ("held-out", split.test)):
        s = segs[0]
        yh = D.simulate_segment(rb, s)
        x = np.asarray(rb.hysteresis_input(jnp.asarray(s.u), jnp.asarray(s.dt)))
        sig = candidate_signals(s.time, s.u, yh, s.dt, x=x, extra=s.extra)
        base_names = set(sig)
        u = np.asarray(s.u, float)
        for k, v in (s.extra or {}).items():
            v = np.asarray(v, float)
            dv = v - v.mean()
            sig[f"extra:{k} x input"] = dv * u
            sig[f"extra:{k} x input^2"] = dv * u * u
            sig[f"extra:{k} x thermal_state"] = dv * x * x
        dur = float(s.time[-1] - s.time[0])
        for tau in sorted({max(f * dur, 2 * float(s.dt)) for f in TAU_FRACTIONS}):
            for k in list(sig):
                if k.startswith("extra:"):
                    sig[f"lp{tau:.3g}s:{k}"] = lowpass(sig[k], float(s.dt), tau)
        sig = {k: v[s.mask] for k, v in sig.items()}
        e = np.asarray(s.y)[s.mask] - yh[s.mask]
        c = signal_correlations(e, sig)
        top = sorted(c.items(), key=lambda kv: -abs(kv[1]["corr"]))
        top_base = [kv for kv in top if kv[0] in base_names][:3]
        print(f"{arg} {case['variant']} {part}: now {[(k, round(v['corr'], 2)) for k, v in top_base]} | with interactions {[(k, round(v['corr'], 2)) for k, v in top[:4]]}", flush=True)
