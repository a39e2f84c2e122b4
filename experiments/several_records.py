"""Several records of one rig that start in different states: the joint fit's training and leave-one-record-out error.

Each set holds records of ONE independent plant (tests/indep_plant.py, plain numpy, no smafl_jax code; one seed = one
plant: thresholds, tilts, thermal rate, sensor) under different drives, rates and starts, written to CSV and fitted
through the command line of the checkout ROOT (`smafl fit A.csv B.csv ... --model cascade`), so that the code before a
change and after it can be run on the same records side by side.  Reported per set: training RMSE / noise SD, the
leave-one-record-out mean RMSE / noise SD and per held-out record, the fitted thermal time constant against the plant's,
and the fit's wall time.  Session 33 (per-record thermal starts): see experiments/results/several_records_session33.md.

    python experiments/several_records.py ROOT OUT.json [SEED ...]     (default seeds 31 41 51)
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(HERE / "tests"))

import indep_plant  # noqa: E402  (plain numpy; shares no code with smafl_jax)

#: set name -> records (drive, rate Hz, minutes, start); every record of a set comes from the same plant (seed)
SETS = {
    "mixed starts": [("pwm", 25, 8, "cold"), ("multisine", 25, 8, "warm"), ("steps", 10, 12, "mid")],
    "warm + cold": [("pwm", 25, 8, "cold"), ("multisine", 50, 5, "warm")],
    "alike (cold)": [("pwm", 25, 8, "cold"), ("multisine", 25, 8, "cold")],
}


def _fit(root: str, csvs: list[Path], out: Path) -> tuple[dict, float]:
    """``(fit.json, wall s)`` of ``smafl fit CSV... --model cascade`` run by the checkout ``root``."""
    code = (
        "import sys; sys.path.insert(0, sys.argv.pop(1)); import smafl_jax; "
        "assert smafl_jax.__file__.startswith(sys.path[0]), smafl_jax.__file__; "
        "from smafl_jax.cli import main; sys.exit(main())"
    )
    args = [sys.executable, "-c", code, root, "fit", *map(str, csvs), "--model", "cascade", "--no-figures", "--out", str(out)]
    t0 = time.perf_counter()
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    p = subprocess.run(args, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if p.returncode:
        raise RuntimeError(f"smafl fit failed ({p.returncode}):\n{p.stdout[-2000:]}\n{p.stderr[-2000:]}")
    return json.loads((out / "fit.json").read_text()), wall


def main() -> None:
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    root, out_json = sys.argv[1], Path(sys.argv[2])
    seeds = [int(s) for s in sys.argv[3:]] or [31, 41, 51]
    rows = json.loads(out_json.read_text()) if out_json.exists() else []
    done = {(r["seed"], r["set"]) for r in rows}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in seeds:
            for name, spec in SETS.items():
                if (seed, name) in done:
                    continue
                csvs, truths = [], []
                for j, (drive, rate, minutes, start) in enumerate(spec):
                    rec = indep_plant.make_record(seed, drive=drive, rate_hz=rate, minutes=minutes, start=start)
                    path = Path(tmp) / f"s{seed}_{j}_{drive}{rate}_{start}.csv"
                    indep_plant.write_csv(path, rec)
                    csvs.append(path)
                    truths.append(rec)
                doc, wall = _fit(root, csvs, Path(tmp) / f"out_{seed}_{len(rows)}")
                noise = float(truths[0]["noise_sd"])
                th = doc["model"]["thermal"]
                row = {
                    "seed": seed,
                    "set": name,
                    "records": [p.name for p in csvs],
                    "noise_sd": noise,
                    "train_x_noise": doc["metrics"]["train"]["rmse"] / noise,
                    "loro_x_noise": doc["metrics"]["validation"]["rmse"] / noise,
                    "loro_per_record_x_noise": [
                        f["model"]["rmse"] / noise if f["model"] else None for f in doc["validation"]["folds"]
                    ],
                    "loro_rule": doc["split"]["rule"],
                    "tau_fit_s": 1.0 / th["k1"],
                    "tau_plant_s": 1.0 / truths[0]["truth"]["thermal"]["k1"],
                    "per_record_start": doc.get("per_record_start"),
                    "wall_s": wall,
                }
                rows.append(row)
                tmp_json = out_json.with_suffix(".tmp")
                tmp_json.write_text(json.dumps(rows, indent=1))
                os.replace(tmp_json, out_json)  # one row at a time: an interrupted run keeps what it measured
                print(
                    f"seed {seed} {name}: train {row['train_x_noise']:.2f}x, LORO {row['loro_x_noise']:.2f}x "
                    f"({', '.join(f'{v:.2f}' for v in row['loro_per_record_x_noise'] if v is not None)}), "
                    f"tau {row['tau_fit_s']:.1f} s (plant {row['tau_plant_s']:.1f}), {wall:.0f} s",
                    flush=True,
                )


if __name__ == "__main__":
    main()
