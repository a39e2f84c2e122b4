"""Probe: why does matrix cell PWM cold 25 Hz seed 11 hold out at 11x noise with training at 1.1x?"""
import json, sys, time
from pathlib import Path
import numpy as np
sys.path.insert(0, "tests")
import indep_plant as ip
import smafl_jax as sj
from smafl_jax.report import fit_record

seed = int(sys.argv[1]) if len(sys.argv) > 1 else 11
drive = sys.argv[2] if len(sys.argv) > 2 else "pwm"
r = ip.make_record(seed, minutes=10, drive=drive, rate_hz=25, start="cold")
h0, sd = r["heldout_start"], r["noise_sd"]
print(json.dumps({k: v for k, v in r["truth"].items() if k not in ("effect",)}, default=str)[:3000])
print(r["meta"])
p = f"/tmp/s35_{seed}_{drive}.csv"; ip.write_csv(p, r)
rec = sj.load_record(p)
p70 = f"/tmp/s35_{seed}_{drive}_70.csv"
sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
t0 = time.time()
model, doc, _ = fit_record(sj.load_record(p70))
print("fit s", time.time() - t0)
yh = np.asarray(sj.simulate(model, rec.u, rec.dt)); e = yh - rec.y
print("train", np.sqrt(np.mean(e[:h0]**2))/sd, "held", np.sqrt(np.mean(e[h0:]**2))/sd)
np.savez(f"/tmp/s35_{seed}_{drive}.npz", yh=yh, y=rec.y, u=rec.u, yc=r["y_clean"], h0=h0)
sj.save_model(f"/tmp/s35_{seed}_{drive}_model.json", model) if hasattr(sj, "save_model") else None
# where is the held-out error: by blocks
blk = np.array_split(np.arange(h0, len(e)), 6)
print("held blocks", [round(float(np.sqrt(np.mean(e[b]**2))/sd), 2) for b in blk])
print("settings", json.dumps({k: doc["settings"].get(k) for k in ("structure", "start_screening", "memory")}, default=str)[:2000])
