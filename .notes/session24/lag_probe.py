"""Is plant B's output sensor lag what keeps the static Gaussian Preisach on the TRUE temperature above the noise?
For the records with a lag: the same fit on the output the plant had before its sensor lag (noise and quantum as the
plant adds them), vs the recorded output.  RMSE / noise on the first 70 % (train_x) and the last 30 % (held_x).
    python lag_probe.py OUT.jsonl"""
import json, os, sys
from pathlib import Path
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT / "experiments"), str(ROOT / "tests")]
os.environ["OPENBLAS_NUM_THREADS"] = "1"
import fit_plant_b as fb
import indep_plant_b as pb
import smafl_jax as sj
from smafl_jax.report import fit_record

out = sys.argv[1]
MODE = sys.argv[2] if len(sys.argv) > 2 else "T"  # "T": static G on the true temperature; "V": the G cascade on the voltage
for c in fb.grid([6, 7], 10.0):
    if c["rate_hz"] not in (5, 25):
        continue
    r = pb.make_record(c["seed"], **{k: v for k, v in c.items() if k != "seed"}, linear_thermal=True)
    tr = r["truth"]
    if tr["hysteresis"]["class"] != "preisach" or tr["sensor_lag_s"] < 0.2 or c["rate_hz"] != 25:
        continue
    h0, dt, T = r["heldout_start"], 1.0 / c["rate_hz"], tr["temperature"]
    # the plant's output before its sensor lag, rebuilt from its parts
    y = tr["stroke_mm"] * tr["fraction"] + tr["expansion_mm_per_K"] * (T - tr["thermal"]["ta"])
    rng = np.random.default_rng(0)
    sign = 1.0 if tr["sensor"] == "displacement" else -1.0
    ynl = tr["length_offset_mm"] + sign * y if sign < 0 else y
    ynl = np.round((ynl + rng.normal(0, r["noise_sd"], len(ynl))) / tr["quantum_mm"]) * tr["quantum_mm"]
    for label, yy in (("lagged", r["output"]), ("no_lag", ynl)):
        u = T if MODE == "T" else r["voltage"]
        rec = sj.Record.from_arrays(r["time"][:h0], u[:h0], yy[:h0], input_name="temperature_C" if MODE == "T" else "voltage_V",
                                    output_name="displacement_mm")
        m, doc, _ = fit_record(rec, model="preisach-gauss" if MODE == "T" else "cascade-preisach-gauss")
        e = np.asarray(sj.simulate(m, u, dt)) - yy
        row = {"name": fb.name_of(c), "mode": MODE, "y": label, "lag": tr["sensor_lag_s"],
               "train_x": float(np.sqrt(np.mean(e[:h0] ** 2)) / r["noise_sd"]),
               "held_x": float(np.sqrt(np.mean(e[h0:] ** 2)) / r["noise_sd"])}
        print(json.dumps(row), flush=True)
        with open(out, "a") as f:
            f.write(json.dumps(row) + "\n")
