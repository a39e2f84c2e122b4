"""Session 63: the diagnosis' base on independent records whose held-out block it misses by far: split and state
coverage, and the held-out error with the base's hysteresis held to its trained effective-input range (below only,
as `smafl fit --hold-input auto` holds a cascade since session 62, and both sides).
python diag_base_hold.py TRUTH:SEED [TRUTH:SEED ...]"""
import sys, tempfile
import numpy as np
import jax.numpy as jnp
sys.path.insert(0, "experiments")
import indep_effects as ie
from smafl_jax.diagnosis import _diagnose as D
from smafl_jax.models._hysteresis import hysteresis_of

for arg in sys.argv[1:]:
    truth, seed = arg.split(":")
    with tempfile.TemporaryDirectory() as tmp:
        rec, case, split, screened, base = ie.diagnosis_start(tmp, truth, int(seed))
    noise = case["noise_rms_measured"]
    rb, cs, _ = D.refined_base(base, screened, split)
    rb, _ = D.converged_base(rb, split)
    h = lambda m: D._held(m, split)["rmse"] / noise
    s = split.train[0]
    x = np.asarray(rb.hysteresis_input(jnp.asarray(s.u), jnp.asarray(s.dt)))
    xt = x[s.mask]
    st = split.test[0]
    xh = np.asarray(rb.hysteresis_input(jnp.asarray(st.u), jnp.asarray(st.dt)))[st.mask]
    lo, hi = float(xt.min()), float(xt.max())
    hy = hysteresis_of(rb)
    out = {}
    for tag, (a, b) in {"below": (lo, None), "both": (lo, hi)}.items():
        if lo <= 0 and tag == "below":
            out[tag] = "n/a (training reached ambient)"
            continue
        out[tag] = round(h(rb.with_hysteresis(hy.with_held(a, b))), 2)
    cov = D.split_coverage(split)
    scov = D.state_coverage(rb, split)
    frac_out = float(np.mean((xh < lo) | (xh > hi)))
    print(f"{truth}:{seed} {case['drive']} {case['start']} base held {h(rb):.2f} | held {out} | state train [{lo:.3g}, {hi:.3g}] "
          f"held-out [{xh.min():.3g}, {xh.max():.3g}] out-of-range {frac_out:.0%} | coverage {cov.get('fraction', cov)} state {scov.get('fraction', scov) if isinstance(scov, dict) else scov}", flush=True)
