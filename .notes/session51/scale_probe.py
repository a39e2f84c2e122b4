import sys, time, json
sys.path.insert(0, "/work/main/tests")
import numpy as np
import indep_plant as ip
import smafl_jax as sj
from smafl_jax.report import fit_record
seed, scale, offset = int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
r = ip.make_record(seed, drive="multisine", rate_hz=25, minutes=10.0, start="cold")
h0 = r["heldout_start"]
y = np.asarray(r["y"]) * scale + offset
p70 = f"/tmp/s51/scale/rec70_{seed}_{scale}_{offset}.csv"
sj.atomic_write_csv(p70, {"time_s": np.asarray(r["time"])[:h0], "voltage_V": np.asarray(r["u"])[:h0], "displacement_mm": y[:h0]})
t0 = time.time()
model, doc, _ = fit_record(sj.load_record(p70))
yh = np.asarray(sj.simulate(model, np.asarray(r["u"]), r["dt"]))
sd = r["noise_sd"] * abs(scale)
e = yh - y
print(json.dumps({"seed": seed, "scale": scale, "offset": offset, "train": float(np.sqrt(np.mean(e[:h0] ** 2)) / sd),
                  "held": float(np.sqrt(np.mean(e[h0:] ** 2)) / sd), "s": time.time() - t0,
                  "chosen": doc["settings"].get("structure_choice", {}).get("chosen")}), flush=True)
