"""How much of plant D's misfit a second, slower thermal mode would remove (experiments/indep_plant_d.py).

The cascade's thermal stage relaxes ``q`` (V^2 units) to ``U^2`` at one rate.  A slow node (sleeve, fishing-line core,
clamps) that warms with the drive makes the wire relax instead to ``(1 - c) U^2 + c LP(U^2, tau_s)``, its surroundings
warmed by the low-passed heat.  That model needs no change to the toolkit to be tried: the default fit of the record
with the drive replaced by ``U' = sqrt((1 - c) U^2 + c LP(U^2, tau_s))`` is exactly a cascade with that slow mode (the
cascade's own lag then filters ``U'^2``).  For each ``(c, tau_s)`` on a small grid the default fit (`fit_record`,
first 70 % of the record) is scored on its own validation block and on the held-out last 30 %; ``c = 0`` is today's fit.
The grid point a user could pick is the one with the lowest validation RMSE (the held-out part is never looked at).

    python experiments/plant_d_thermal_mass.py OUT.jsonl --seed 1 --cell triangle:50:cold:length --physics sleeve
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "experiments"))
sys.path.insert(0, str(ROOT))

import indep_plant_d as pd  # noqa: E402

GRID = [(0.0, None), (0.25, 40.0), (0.25, 120.0), (0.5, 40.0), (0.5, 120.0)]


def slow_drive(u, dt, c, tau):
    """``sqrt((1 - c) U^2 + c LP(U^2, tau))``: the drive whose Joule heat carries the slow node (exact ZOH low-pass)."""
    if c == 0.0:
        return np.asarray(u, dtype=np.float64)
    h = np.asarray(u, dtype=np.float64) ** 2
    a = np.exp(-dt / tau)
    lp = np.empty_like(h)
    z = h[0]  # at rest with the first drive sample
    for k, hk in enumerate(h):
        lp[k] = z
        z = a * z + (1.0 - a) * hk
    return np.sqrt((1.0 - c) * h + c * lp)


def main(argv=None):
    import smafl_jax as sj
    from smafl_jax.report import fit_record

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--cell", default="triangle:50:cold:length")
    ap.add_argument("--physics", nargs="*", default=list(pd.PHYSICS))
    ap.add_argument("--minutes", type=float, default=10.0)
    a = ap.parse_args(argv)
    drive, rate, start, sensor = a.cell.split(":")
    r = pd.make_record(a.seed, drive=drive, rate_hz=float(rate), minutes=a.minutes, start=start, sensor=sensor,
                       physics=tuple(a.physics))  # fmt: skip
    h0, sd, dt = r["heldout_start"], r["noise_sd"], 1.0 / float(rate)
    for c, tau in GRID:
        u = slow_drive(r["voltage"], dt, c, tau)
        rec = sj.Record.from_arrays(r["time"][:h0], u[:h0], r["output"][:h0], input_name="voltage_V",
                                        output_name="displacement_mm")  # fmt: skip
        t0 = time.perf_counter()
        m, doc, _ = fit_record(rec)
        yh = np.asarray(sj.simulate(m, u, dt))
        e = yh - r["output"]
        row = {
                "seed": a.seed, "cell": a.cell, "physics": a.physics, "c": c, "tau_s": tau,
                "validation_x": doc["metrics"]["validation"]["rmse"] / sd,
                "train_x": float(np.sqrt(np.mean(e[:h0] ** 2)) / sd),
                "held_x": float(np.sqrt(np.mean(e[h0:] ** 2)) / sd),
                "chosen": doc["settings"]["structure_choice"]["chosen"],
                "seconds": time.perf_counter() - t0,
                "truth": r["truth"]["wire"],
            }  # fmt: skip
        with open(a.out, "a") as fh:
            fh.write(json.dumps(row) + "\n")
        print(
            f"c {c} tau_s {tau}: validation {row['validation_x']:.2f}x train {row['train_x']:.2f}x held "
            f"{row['held_x']:.2f}x ({row['chosen']}, {row['seconds']:.0f} s)",
            flush=True,
        )


if __name__ == "__main__":
    main()
