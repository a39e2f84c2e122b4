"""Probe: operator thresholds spaced geometrically (0.02 .. 0.5 of the span) instead of i / (2n); one cell's 70 %.

python .notes/session58/geo_grid.py FULL.csv PART.csv geo|default [model]
"""
import sys, json, time
import numpy as np
import smafl_jax as sj
import smafl_jax.models._eupi as E
from smafl_jax.report import fit_record

full, part, kind = sys.argv[1:4]
model = sys.argv[4] if len(sys.argv) > 4 else "cascade"
if kind == "geo":
    def threshold_grid(n):
        n = int(n)
        if n <= 1:
            return np.full(n, 0.25)
        return 0.5 * 0.04 ** ((n - 1 - np.arange(n)) / (n - 1))
    E.threshold_grid = threshold_grid
truth = json.load(open(full.replace(".csv", ".truth.json")))
rec, p70 = sj.load_record(full), sj.load_record(part)
t0 = time.time()
m, doc, _ = fit_record(p70, model=model, **({"slow_mode": "off"} if model != "auto" else {}))
yh = np.asarray(sj.simulate(m, rec.u, rec.dt))
e = yh - rec.y; h0 = truth["heldout_start"]; sd = truth["noise_sd"]
print(json.dumps(dict(kind=kind, model=model, train=float(np.sqrt(np.mean(e[:h0] ** 2)) / sd), held=float(np.sqrt(np.mean(e[h0:] ** 2)) / sd),
      val=(doc["metrics"].get("validation") or {}).get("rmse", np.nan) / sd, seconds=time.time() - t0)))
