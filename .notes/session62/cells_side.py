"""Random plant-A cells (session-48 draw): default fit_record on the first 70 %, held-out error with the cascade's
hysteresis input free, held on both sides, the low side only, the high side only (post-hoc).

python .notes/session62/cells_side.py ROOT OUT.jsonl SEED...
"""
import sys, json, time
from pathlib import Path
root = sys.argv[1]; sys.path.insert(0, str(Path(root).resolve())); sys.path.insert(0, "/work/main/tests")
import numpy as np, indep_plant as ip, smafl_jax as sj
from smafl_jax.report import fit_record
from smafl_jax.models._hysteresis import hysteresis_of
from smafl_jax.models._range import effective_values
out = open(sys.argv[2], "a")
for s in map(int, sys.argv[3:]):
    rng = np.random.default_rng([s, 4848])
    fam = str(rng.choice(ip.FAMILIES)); rate = round(float(np.exp(rng.uniform(np.log(5.0), np.log(100.0)))), 1)
    minutes = round(min(float(rng.uniform(5.0, 20.0)), 60000 / rate / 60.0), 1)
    cell = {"drive": fam, "rate_hz": rate, "start": str(rng.choice(ip.STARTS)), "orientation": str(rng.choice(ip.ORIENTATIONS))}
    r = ip.make_record(s, minutes=minutes, **cell); h0, sd = r["heldout_start"], r["noise_sd"]
    p = f"/tmp/s62_cells/m_{s}.csv"; Path(p).parent.mkdir(exist_ok=True); ip.write_csv(p, r); rec = sj.load_record(p)
    p70 = f"/tmp/s62_cells/m70_{s}.csv"
    sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
    t0 = time.time(); model, doc, _ = fit_record(sj.load_record(p70)); sec = time.time() - t0
    h = hysteresis_of(model); row = dict(seed=s, cell=cell, minutes=minutes, type=type(h).__name__, seconds=sec)
    rngx = doc["data"].get("effective_input_range")
    if rngx is None or not hasattr(model, "with_hysteresis"):
        row["skip"] = "no effective range"
    else:
        lo, hi = rngx
        xe = effective_values(model, rec.u, rec.dt)
        row.update(below=float(np.mean(xe[h0:] < lo)), above=float(np.mean(xe[h0:] > hi)))
        for k, b in {"free": None, "both": (lo, hi), "low": (lo, 1e12), "high": (-1e12, hi)}.items():
            m = model if b is None else model.with_hysteresis(h.with_held(*b))
            y = np.asarray(sj.simulate(m, rec.u, rec.dt))
            row[k] = float(np.sqrt(np.mean((y[h0:] - rec.y[h0:]) ** 2)) / sd)
    out.write(json.dumps(row) + "\n"); out.flush(); print(json.dumps(row), flush=True)
