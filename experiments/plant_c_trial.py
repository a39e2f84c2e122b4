"""New-user trial 7 (session 43) on plant C (experiments/indep_plant_c.py): `smafl fit` defaults on the first 70 % of
each record, `smafl simulate` on the whole record and on new runs of the same plant; RMSE over the record's true noise
SD on the held-out 30 % (against the measured and the noise-free output) and on each new run (noise-free).

    python experiments/plant_c_trial.py WORK [--smafl /path/to/smafl] [--only r01 r03]

Records (NAME plant_seed drive_seed drive fs minutes sensor start excursion [sees]) are those of trial 7; WORK/NAME holds
the CSVs, fit/ and predictions; WORK/rows.jsonl one line per record.  Pass an older checkout's `smafl` to compare codes.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import indep_plant_c as pc

RECORDS = {
    "r01": (11, 111, "pwm", 10, 12, "displacement", "cold", 0, None),
    "r02": (12, 121, "multisine", 25, 10, "length", "cold", 0, None),
    "r03": (13, 131, "steps", 5, 20, "displacement", "cold", 0, None),
    "r04": (14, 141, "pwm", 50, 10, "length", "cold", 0, None),
    "r05": (15, 151, "steps", 100, 8, "displacement", "warm", 0, None),
    "r06": (16, 161, "multisine", 10, 15, "displacement", "cold", 1, None),
    "r07": (17, 171, "steps", 25, 12, "length", "cold", 1, None),
    "r08": (18, 183, "pwm", 5, 20, "displacement", "warm", 0, "temp"),
    "r09": (19, 194, "multisine", 50, 10, "displacement", "cold", 0, "temp"),
    "r10": (20, 201, "steps", 10, 15, "length", "cold", 0, None),
}
#: New runs of a record's plant (same sensor mount: the record's offset), scored with that record's fit.
NEW_RUNS = {
    "r01b": ("r01", (11, 112, "steps", 10, 12, "displacement", "cold", 0, None)),
    "r03b": ("r03", (13, 132, "multisine", 5, 15, "displacement", "cold", 0, None)),
    "r09b": ("r09", (19, 192, "pwm", 50, 10, "displacement", "cold", 0, "temp")),
    "r10c": ("r10", (20, 202, "steps", 10, 15, "length", "warm", 0, None)),
    "r10d": ("r10", (20, 202, "steps", 10, 15, "length", "cold", 0, None)),
}


def _write(folder: Path, name: str, args, offset=None):
    folder.mkdir(parents=True, exist_ok=True)
    if offset is not None:
        os.environ["PLANT_C_OFFSET"] = repr(offset)
    try:
        t, u, meas, clean, meta = pc.make_record(*args)
    finally:
        os.environ.pop("PLANT_C_OFFSET", None)
    col = "length_mm" if meta["sensor"] == "length" else "displacement_mm"
    n70 = int(0.7 * len(t))
    pc.write_csv(folder / f"{name}_whole.csv", t, u, meas, col)
    pc.write_csv(folder / f"{name}_first70.csv", t[:n70], u[:n70], meas[:n70], col)
    return meas, clean, meta, n70


def _predict(smafl: str, fit: Path, csv: Path, out: Path) -> np.ndarray:
    run = subprocess.run([smafl, "simulate", str(fit), str(csv), "--out", str(out)], capture_output=True, text=True)
    if run.returncode:
        raise RuntimeError(run.stderr)
    (out.parent / f"{out.stem}_stderr.txt").write_text(run.stderr)
    data = np.genfromtxt(out, delimiter=",", names=True)
    return np.asarray(data[next(n for n in data.dtype.names if n.endswith("_model"))])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("work", type=Path)
    ap.add_argument("--smafl", default="smafl")
    ap.add_argument("--only", nargs="*", default=None)
    a = ap.parse_args()
    rmse = lambda e: float(np.sqrt(np.mean(np.square(e))))
    for name, args in RECORDS.items():
        if a.only and name not in a.only:
            continue
        d = a.work / name
        meas, clean, meta, n70 = _write(d, name, args)
        sd = meta["noise_sd"]
        t0 = time.time()
        fit = subprocess.run([a.smafl, "fit", str(d / f"{name}_first70.csv"), "--out", str(d / "fit"), "--no-figures"],
                             capture_output=True, text=True)  # fmt: skip
        (d / "fit_stderr.txt").write_text(fit.stderr)
        row = {"record": name, "args": args, "fit_seconds": time.time() - t0, "fit_rc": fit.returncode}
        if fit.returncode == 0:
            doc = json.loads((d / "fit" / "fit.json").read_text())
            row["chosen"] = (doc["settings"].get("structure_choice") or {}).get("chosen", doc["settings"]["structure"])
            y = _predict(a.smafl, d / "fit" / "fit.json", d / f"{name}_whole.csv", d / "pred.csv")
            row.update(train=rmse(y[:n70] - meas[:n70]) / sd, held=rmse(y[n70:] - meas[n70:]) / sd,
                       held_clean=rmse(y[n70:] - clean[n70:]) / sd)  # fmt: skip
            for new, (base, nargs) in NEW_RUNS.items():
                if base != name:
                    continue
                _, nclean, _, _ = _write(d / new, new, nargs, offset=meta["offset_mm"] if meta["sensor"] == "length" else None)
                yn = _predict(a.smafl, d / "fit" / "fit.json", d / new / f"{new}_whole.csv", d / new / "pred.csv")
                row[f"new_run_{new}_clean"] = rmse(yn - nclean) / sd
        print(json.dumps(row), flush=True)
        with open(a.work / "rows.jsonl", "a") as f:
            f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
