"""Plant B fits (fit_plant_b work dirs): held-out error as is, held both sides, held low side only, held high side only."""
import sys, json, glob, re
from pathlib import Path
import numpy as np
import smafl_jax as sj
from smafl_jax.models._hysteresis import hysteresis_of, thermal_of
rows = []
for pat in sys.argv[1:]:
  for d in sorted(glob.glob(pat)):
    d = Path(d); fj = next(d.rglob("fit.json"), None)
    if fj is None: continue
    doc = json.loads(fj.read_text()); model = sj.load_model(fj)
    h = hysteresis_of(model)
    if h is None or not hasattr(h, "with_held") or not hasattr(model, "with_hysteresis"): continue
    # "free": the saved model with any hold taken off (session 62's default holds a cascade's cold side)
    h = h.with_held(None); model = model.with_hysteresis(h)
    tr = sj.load_record(d / "first70.csv"); full = sj.load_record(d / "full.csv"); h0 = len(tr)
    sd = float(re.search(r"_n([0-9.]+)", d.name).group(1))
    lo, hi = doc["data"].get("effective_input_range") or doc["data"]["input_range"]
    out = {}
    sp = hi - lo
    for k, b in {"free": None, "both": (lo, hi), "low": (lo, 1e12), "high": (-1e12, hi), "low10": (lo - 0.1 * sp, 1e12), "low25": (lo - 0.25 * sp, 1e12)}.items():
        m = model if b is None else model.with_hysteresis(h.with_held(*b))
        y = np.asarray(sj.simulate(m, full.u, full.dt))
        out[k] = float(np.sqrt(np.mean((y[h0:] - full.y[h0:]) ** 2)) / sd)
    x = np.asarray(sj.simulate(model, full.u, full.dt))
    from smafl_jax.models._range import effective_values
    xe = effective_values(model, full.u, full.dt)
    below = float(np.mean(xe[h0:] < lo)) if xe is not None else float("nan"); above = float(np.mean(xe[h0:] > hi)) if xe is not None else float("nan")
    rows.append(out); print(f"{d.name:42s} {type(h).__name__:16s} below {below:.2f} above {above:.2f} " + " ".join(f"{k} {v:8.2f}" for k, v in out.items()), flush=True)
r = np.array([[o[k] for k in ("free", "both", "low", "high", "low10", "low25")] for o in rows])
print("n", len(r), "gm free %.2f both %.2f low %.2f high %.2f low10 %.2f low25 %.2f" % tuple(np.exp(np.mean(np.log(r), axis=0))))
