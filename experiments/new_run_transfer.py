"""New runs of a fitted plant A (tests/indep_plant.py): fit one record, predict another record of the same plant.

A user fits one record and runs the model on the next day's record; the held-out block of the same record does not
measure that.  Cells of issue 18's matrix with the same seed, start and sensor share one plant (``random_truth`` is
drawn from the seed and those two overrides), so each fitted record is scored on its own held-out 30 % and on the
whole of its partner record (another drive family), against the partner's noise-free output, RMSE over the noise SD.
``in_range`` scores the partner only up to the first sample whose true hysteresis input leaves the fitted record's
trained range by more than 1 % of that range (after it the prediction is extrapolation, reported separately).

    OPENBLAS_NUM_THREADS=1 python experiments/new_run_transfer.py OUT.jsonl 7 11 13 [--opts '{"gain_prior": 0.1}'] [--cells PWM]
    python experiments/new_run_transfer.py --table A.jsonl B.jsonl

Rows are appended to OUT.jsonl as each fit finishes (a rerun appends; the table reads the last row per key).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import indep_plant as ip

#: (fitted cell, partner cell): same start and sensor, so the same plant for a given seed.
PAIRS = {
    "multisine, cold, 25 Hz": "PWM, cold, 25 Hz",
    "PWM, cold, 25 Hz": "multisine, cold, 25 Hz",
    "PWM, length sensor, 25 Hz": "random_levels, cold, 20 Hz, length sensor",
    "random_levels, cold, 20 Hz, length sensor": "PWM, length sensor, 25 Hz",
}


def _rmse(e) -> float:
    return float(np.sqrt(np.mean(np.square(e)))) if len(e) else float("nan")


def run(out: Path, seeds, opts: dict, minutes: float, cells: str = "") -> None:
    import smafl_jax as sj
    from smafl_jax.report import fit_record

    for seed in seeds:
        recs = {cell: ip.make_record(seed, minutes=minutes, **ip.MATRIX_CELLS[cell]) for cell in PAIRS}
        for cell, partner in PAIRS.items():
            if cells not in cell:
                continue
            r, p = recs[cell], recs[partner]
            if r["truth"]["hysteresis"] != p["truth"]["hysteresis"]:
                raise RuntimeError(f"seed {seed}: {cell!r} and {partner!r} are not the same plant")
            h0, sd = r["heldout_start"], r["noise_sd"]
            with tempfile.TemporaryDirectory() as tmp:
                ip.write_csv(Path(tmp) / "whole.csv", r)
                rec = sj.load_record(Path(tmp) / "whole.csv")
                sj.atomic_write_csv(
                    Path(tmp) / "first70.csv", {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]}
                )
                t0 = time.time()
                model, doc, _ = fit_record(sj.load_record(Path(tmp) / "first70.csv"), **opts)
                seconds = time.time() - t0
            y = np.asarray(sj.simulate(model, r["u"], r["dt"]))
            yp = np.asarray(sj.simulate(model, p["u"], p["dt"]))
            ep = (yp - p["y_clean"]) / p["noise_sd"]
            x_tr = r["sim"]["x_h"][:h0]
            lo, hi = float(np.min(x_tr)), float(np.max(x_tr))
            tol = 0.01 * (hi - lo)
            out_of = np.flatnonzero((p["sim"]["x_h"] < lo - tol) | (p["sim"]["x_h"] > hi + tol))
            first_exit = int(out_of[0]) if out_of.size else len(ep)
            row = {
                "seed": seed,
                "cell": cell,
                "partner": partner,
                "opts": opts,
                "chosen": (doc["settings"].get("structure_choice") or {}).get("chosen", doc["settings"]["structure"]),
                "train": _rmse(y[:h0] - r["y"][:h0]) / sd,
                "held": _rmse(y[h0:] - r["y"][h0:]) / sd,
                "new_run": _rmse(ep),
                "new_run_in_range": _rmse(ep[:first_exit]),
                "new_run_in_range_fraction": first_exit / len(ep),
                "new_run_outside_fraction": out_of.size / len(ep),
                "largest_gain": ((doc.get("solver") or {}).get("gain_prior") or {}).get("largest_gain"),
                "seconds": seconds,
            }
            print(json.dumps(row), flush=True)
            with open(out, "a") as fh:
                fh.write(json.dumps(row) + "\n")


def table(paths) -> None:
    runs = []
    for path in paths:
        rows = {}
        for line in Path(path).read_text().splitlines():
            row = json.loads(line)
            rows[(row["seed"], row["cell"])] = row
        runs.append(rows)
    keys = sorted(set.intersection(*(set(r) for r in runs)), key=lambda k: (k[0], k[1]))
    names = [Path(p).stem for p in paths]
    print("| seed | fitted record -> new run | " + " | ".join(f"{n}: held / new (in range)" for n in names) + " |")
    print("| --- | --- | " + " | ".join("---" for _ in names) + " |")
    for k in keys:
        cells = " | ".join(f"{r[k]['held']:.2f} / {r[k]['new_run']:.1f} ({r[k]['new_run_in_range']:.1f})" for r in runs)
        print(f"| {k[0]} | {k[1]} -> {runs[0][k]['partner']} | {cells} |")
    for n, r in zip(names, runs):
        held = np.array([r[k]["held"] for k in keys])
        new = np.array([r[k]["new_run"] for k in keys])
        inr = np.array([r[k]["new_run_in_range"] for k in keys])
        gm = lambda a: float(np.exp(np.mean(np.log(a))))
        print(
            f"\n- {n} ({len(keys)} fits): held out gm {gm(held):.2f}x, within 1.5x {int(np.sum(held <= 1.5))}; "
            f"new run gm {gm(new):.2f}x (in range {gm(inr):.2f}x), within 3x {int(np.sum(new <= 3))}, "
            f"within 10x {int(np.sum(new <= 10))}, worst {new.max():.0f}x"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("args", nargs="+")
    ap.add_argument("--table", action="store_true")
    ap.add_argument("--opts", default="{}", help="JSON keyword options of fit_record")
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--cells", default="", help="fit only the cells whose name contains this text")
    a = ap.parse_args()
    if a.table:
        table(a.args)
    else:
        run(Path(a.args[0]), [int(s) for s in a.args[1:]], json.loads(a.opts), a.minutes, a.cells)


if __name__ == "__main__":
    main()
