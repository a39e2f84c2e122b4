"""Issue 18: how well can our model class do on the failing matrix cells if it saw the plant's TRUE hysteresis input?

For each cell (tests/indep_plant.py, 10-minute records) an EUPI with trained thresholds, tilts and fitted memory
(`fit_record(model="eupi", thresholds=True, tilts=True)`) is fitted on the first 70 % against the plant's own
hysteresis input (no thermal part to identify) and scored on the last 30 % (RMSE / noise SD). If this oracle is far
above 1x, the held-out part is extrapolation to branches the training never visited, not a fitting failure.

    python experiments/oracle_cells.py     (prints one JSON line per cell; about 1-2 min per cell)
"""

import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

import indep_plant as ip  # noqa: E402

import smafl_jax as sj  # noqa: E402
from smafl_jax.report import fit_record  # noqa: E402

CELLS = {
    "pwm_cold": dict(drive="pwm", rate_hz=25, start="cold"),
    "stair_warm": dict(drive="staircase", rate_hz=10, start="warm"),
    "pwm_len": dict(drive="pwm", rate_hz=25, start="cold", orientation="length"),
    "ms_mid": dict(drive="multisine", rate_hz=10, start="mid"),
}
todo = [("pwm_cold", 7), ("pwm_cold", 11), ("stair_warm", 7), ("stair_warm", 11), ("pwm_len", 7), ("ms_mid", 13)]
for cell, seed in todo:
    r = ip.make_record(seed, minutes=10, **CELLS[cell])
    h0, sd = r["heldout_start"], r["noise_sd"]
    x = ip._core(r["truth"], r["u"], r["dt"], upto="x")["x_h"]
    t = np.arange(len(x)) * r["dt"]
    p = f"/tmp/smafl_oracle_{cell}_{seed}.csv"
    sj.atomic_write_csv(p, {"time_s": t[:h0], "temperature_C": x[:h0], "displacement_mm": r["y"][:h0]})
    m, doc, _ = fit_record(
        sj.load_record(p, input="temperature_C", output="displacement_mm"), model="eupi", thresholds=True, tilts=True
    )
    yh = np.asarray(sj.simulate(m, x, r["dt"]))
    e = lambda i, j: float(np.sqrt(np.mean((yh[i:j] - r["y"][i:j]) ** 2)) / sd)
    # how much of the held-out hysteresis input lies on branches: fraction of held-out x outside the train range, and new extrema
    print(
        json.dumps(
            {
                "cell": cell,
                "seed": seed,
                "oracle_train": round(e(0, h0), 2),
                "oracle_held": round(e(h0, len(x)), 2),
                "x_train": [round(float(x[:h0].min()), 3), round(float(x[:h0].max()), 3)],
                "x_held": [round(float(x[h0:].min()), 3), round(float(x[h0:].max()), 3)],
                "memory": r["truth"]["hysteresis"]["memory"]["kind"],
                "orient": doc["model"].get("orientation"),
            }
        ),
        flush=True,
    )
