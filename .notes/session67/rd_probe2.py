"""Session 67: whole-record fit of rate_dependence from a captured diagnosis base (`.notes/session65/capture.py TRUTH
SEED OUT.pkl rate_dependence`): the session-66 starts ("old"), weak starts ("smallc"), and the lagged rate with weak
starts ("filt", the class as committed in 1582ae6).  Run with PYTHONPATH at a tree with the lagged class:
python rd_probe2.py OUT.pkl   (outputs of the 35 records: probes/)"""
import sys, pickle, time
import numpy as np
from smafl_jax.diagnosis import _diagnose as D
from smafl_jax.effects.catalogue import RateDependence as RD
from smafl_jax.effects.protocol import Nonlinear, Log
import jax.numpy as jnp
g = pickle.load(open(sys.argv[1], "rb"))
rec, base = g["record"], g["base"]
w = D.whole_record_split(rec)
full = D.Split(w.kind, w.rule, w.train, w.train, w.train_labels, w.train_labels)
b = D.refine_model(D.fit_extended(base, [], full)[0], full)
rb = D.score(b, full.train)[0]["rmse"]
sd = g["case"]["noise_sd"]
out = [f"{sys.argv[1].split('/')[-1]} base {rb/sd:.3f}x"]
filt_nl, filt_grid = RD.nonlinear, RD.grid
variants = {
  "old": (classmethod(lambda cls, ctx: (Nonlinear("c", Log(), 0.5),)), classmethod(lambda cls, ctx: [cls(c=jnp.asarray(c)) for c in (0.1, 0.5, 2.0)])),
  "smallc": (classmethod(lambda cls, ctx: (Nonlinear("c", Log(), 0.5),)), classmethod(lambda cls, ctx: [cls(c=jnp.asarray(c)) for c in (0.003, 0.03, 0.3)])),
  "filt": (filt_nl, filt_grid),
}
for k, (nl, gr) in variants.items():
    RD.nonlinear, RD.grid = nl, gr
    t0 = time.time()
    c0, info = D.fit_extended(b, ["rate_dependence"], full)
    c1 = D.refine_model(c0, full)
    r1 = D.score(c1, full.train)[0]["rmse"]
    e = c1.get("rate_dependence")
    out.append(f"{k}: gain {1 - r1/rb:+.3f} ({r1/sd:.3f}x) c {float(e.c):.4g} tau {float(e.tau):.3g} {time.time()-t0:.0f}s")
print(" | ".join(out), flush=True)
