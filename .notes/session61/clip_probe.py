"""Held-out error with the model's hysteresis input as is, and held to its trained range (post-hoc), on plant-A
excursion records (and any records given by --cells)."""
import sys, json, time
sys.path.insert(0, "/work/main/tests")
import numpy as np, indep_plant as ip, smafl_jax as sj
sys.path.insert(0, "/tmp/s61")
from clip_probe_lib import sim_clipped as _sc, sim_ops_held
from smafl_jax.report import fit_record

KW = dict(drive=sys.argv[2] if len(sys.argv) > 2 else "multisine", rate_hz=25, start="cold", minutes=10.0)
rows = []
for seed in map(int, sys.argv[1].split(",")):
    r = ip.make_record(seed, excursion=True, **KW)
    h0, sd = r["heldout_start"], r["noise_sd"]
    p = f"/tmp/s61/exc_{seed}.csv"; ip.write_csv(p, r); rec = sj.load_record(p)
    p70 = f"/tmp/s61/exc70_{seed}.csv"
    sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
    model, doc, _ = fit_record(sj.load_record(p70))
    rng = doc["data"].get("effective_input_range") or doc["data"]["input_range"]
    ya = np.asarray(sj.simulate(model, rec.u, rec.dt)); yb = _sc(model, rec.u, rec.dt, rng)
    m = 0.25 * (rng[1] - rng[0]); yc = _sc(model, rec.u, rec.dt, (rng[0] - m, rng[1] + m)); yd = sim_ops_held(model, rec.u, rec.dt, rng)
    sp = r["excursion_span"]; a, b = sp["state_start"], sp["state_end"]
    # back in range: after the plant's input returns (span end) to the end
    def sc(yh):
        e = (yh - rec.y) / sd
        return dict(held=float(np.sqrt(np.mean(e[h0:] ** 2))), during=float(np.sqrt(np.mean(e[a:b] ** 2))), after=float(np.sqrt(np.mean(e[b:] ** 2))), before=float(np.sqrt(np.mean(e[h0:a] ** 2))))
    row = dict(seed=seed, type=type(model).__name__, as_is=sc(ya), clipped=sc(yb) if yb is not None else None, margin25=sc(yc) if yc is not None else None, ops_held=sc(yd) if yd is not None else None)
    print(json.dumps(row), flush=True)
