"""Does `smafl simulate`'s branch check flag the records whose held-out part the fit cannot predict?

Two sets of records the toolkit did not make:

- ``plant-b``: the fits of `experiments/fit_plant_b.py` (its work folder: each record's ``first70.csv``,
  ``full.csv`` and ``fit/fit.json``; its results jsonl for the held-out error).  The trained branches are computed
  from the saved model over the first 70 % (what `smafl fit` of that file stores since session 19), then the whole
  record is checked (`smafl_jax.models.branch_check`).
- ``matrix``: records of tests/indep_plant.py (10 min): `smafl fit FIRST70.csv`, then `smafl simulate` of the whole
  record, both as a user runs them; the warnings `simulate` prints are collected.

    python experiments/branch_check_independent.py plant-b [--work /tmp/plant_b_fits]
    python experiments/branch_check_independent.py matrix [--cells "7:PWM, cold, 25 Hz" ...]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import indep_plant  # noqa: E402

import smafl_jax as sj  # noqa: E402
from smafl_jax.models import branch_check, range_check, trained_branches  # noqa: E402

MATRIX = (
    "7:PWM, cold, 25 Hz",
    "13:PWM, cold, 25 Hz",
    "17:PWM, cold, 25 Hz",
    "7:multisine, half-warm, 10 Hz",
    "13:multisine, cold, 25 Hz",
    "13:staircase, warm, 10 Hz",
)


def _gmean(v):
    return float(np.exp(np.mean(np.log(v)))) if len(v) else float("nan")


def plant_b(work: Path) -> None:
    rows = [json.loads(line) for line in (ROOT / "experiments/results/plant_b_default_fit.jsonl").read_text().splitlines()]
    out = []
    for d in rows:
        base = work / d["name"]
        if not (base / "fit" / "fit.json").exists():
            print(f"{d['name']}: no fit in {base} (run experiments/fit_plant_b.py first)")
            continue
        model = sj.load_model(base / "fit" / "fit.json")
        rec = sj.load_record(base / "full.csv")
        h0 = len(sj.load_record(base / "first70.csv"))
        x = np.asarray(model.hysteresis_input(rec.u, rec.dt))
        c = branch_check(x, trained_branches(x[:h0]), dt=rec.dt)
        outside = range_check(x, [float(x[:h0].min()), float(x[:h0].max())], dt=rec.dt)["fraction_outside"]
        out.append((d["name"], d["heldout_x_noise"], c["untrained_span_fraction"], "warning" in c, outside))
        print(
            f"{d['name']:38s} held-out {d['heldout_x_noise']:7.2f}x  untrained span {c['untrained_span_fraction']:.2f}  "
            f"warning {'warning' in c!s:5s}  outside the range {outside:.2f}",
            flush=True,
        )
    warned = [o[1] for o in out if o[3]]
    quiet = [o[1] for o in out if not o[3]]
    good = [o for o in out if o[1] <= 3.0]
    print(f"warned: {len(warned)}, held-out geometric mean {_gmean(warned):.1f}x; not warned: {len(quiet)}, {_gmean(quiet):.1f}x")
    print(f"records within 3x the noise: {len(good)}, warned: {sum(o[3] for o in good)}")
    print(f"warned without leaving the trained range: {sum(o[3] and o[4] == 0 for o in out)}")


def matrix(cells) -> None:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    with tempfile.TemporaryDirectory() as tmp:
        for spec in cells:
            seed, cell = spec.split(":", 1)
            kw = indep_plant.MATRIX_CELLS[cell]
            r = indep_plant.make_record(int(seed), minutes=10, **kw)
            h0 = r["heldout_start"]
            d = Path(tmp) / f"{seed}_{len(os.listdir(tmp))}"
            d.mkdir()

            def cols(sl, r=r):
                return {"time_s": r["time"][sl], "voltage_V": r["u"][sl], "displacement_mm": r["y"][sl]}

            sj.atomic_write_csv(d / "first70.csv", cols(slice(0, h0)))
            sj.atomic_write_csv(d / "full.csv", cols(slice(None)))
            smafl = [sys.executable, "-m", "smafl_jax"]
            subprocess.run([*smafl, "fit", str(d / "first70.csv"), "--out", str(d / "fit"), "--no-figures"], env=env,
                           capture_output=True, check=True)  # fmt: skip
            sim = subprocess.run(
                [*smafl, "simulate", str(d / "fit" / "fit.json"), str(d / "full.csv"), "--out", str(d / "sim.csv")],
                env=env, capture_output=True, text=True, check=True,
            )  # fmt: skip
            y = np.loadtxt(d / "sim.csv", delimiter=",", skiprows=1)[:, 2]
            held = float(np.sqrt(np.mean((y[h0:] - r["y"][h0:]) ** 2)) / r["noise_sd"])
            warns = [w.split(":")[1].strip()[:60] for w in sim.stderr.splitlines() if w.startswith("warning")]
            print(f"seed {seed} {cell}: held-out {held:.2f}x noise; simulate warnings: {warns or 'none'}", flush=True)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("which", choices=("plant-b", "matrix"))
    ap.add_argument("--work", type=Path, default=Path("/tmp/plant_b_fits"))
    ap.add_argument("--cells", nargs="+", default=list(MATRIX))
    a = ap.parse_args()
    plant_b(a.work) if a.which == "plant-b" else matrix(a.cells)
