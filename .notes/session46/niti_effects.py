"""Probe: NiTi 9-record LORO, joint Preisach base vs base + one input/output effect (fit_extended, varpro + NM)."""
import glob, json, sys, time
import numpy as np
import smafl_jax  # noqa
from smafl_jax.data.load import load_records
from smafl_jax.identify._multi_record import _joint_fit  # private: probe
from smafl_jax.diagnosis._diagnose import Segment, Split, fit_extended, refine_model  # private: probe
from smafl_jax.models._simulate import simulate
from smafl_jax.identify._baselines import baselines_doc  # private: probe

effects = sys.argv[2].split(",") if len(sys.argv) > 2 else ["sensor_lead", "sensor_lag", "creep"]
model_name = sys.argv[3] if len(sys.argv) > 3 else "preisach"
paths = sorted(glob.glob("/work/shared/data/real/niti_wire_*.csv"))
recs = load_records(paths, input="temperature_front_C", output="length_signal")
kw = dict(solver="lm", max_steps=300, thresholds=None, tilts=None, grid=None, orientation="auto", thermal_start="auto")
rows = []
for i, rec in enumerate(recs):
    train = [r for j, r in enumerate(recs) if j != i]
    t0 = time.time()
    res, info = _joint_fit(train, model=model_name, progress=False, **kw)
    base = res.model
    split = Split("records", "loro", [Segment(r.time, r.u, r.y, r.dt, r.measured.copy()) for r in train], [])
    row = {"record": rec.name}
    def score(m):
        y = np.asarray(m.simulate(rec.u, rec.dt)) if hasattr(m, "effects") else np.asarray(simulate(m, rec.u, rec.dt))
        k = rec.measured
        return float(np.sqrt(np.mean((y[k] - rec.y[k]) ** 2))) if np.all(np.isfinite(y)) else float("nan")
    row["base"] = score(base)
    for name in effects:
        m, inf = fit_extended(base, name.split("+"), split)  # "a+b": two effects at once (session 52)
        row[name] = score(m)
        row[name + "_params"] = {e.name: {k: float(np.asarray(v)) for k, v in vars(e).items() if np.ndim(v) == 0 and not isinstance(v, str)} for e in m.effects}
    bl = baselines_doc(train, [r.measured for r in train], [rec], [rec.measured], squared=False, model_heldout=None)
    row["static_poly"] = bl["models"]["static_poly"]["heldout"]["rmse"]
    row["seconds"] = time.time() - t0
    print(json.dumps(row), flush=True)
    rows.append(row)
with open(sys.argv[1], "w") as f:
    for r in rows:
        f.write(json.dumps(r) + "\n")
for k in ["base"] + effects:
    ratios = [r[k] / r["static_poly"] for r in rows]
    print(k, "median ratio to static_poly", round(float(np.median(ratios)), 3), [round(x, 2) for x in ratios])
