"""Issue 18: does the default fit reach the noise floor on records this toolkit did not make?

Records come from tests/indep_plant.py (plain numpy, no smafl_jax code: its own thresholds, tilts,
initial operator memory, hysteresis on temperature or effective voltage, its own thermal scheme,
sensor noise and quantisation).  Each record is fitted on its first 70 % with the settings a user
gets (`fit_record` defaults = `smafl fit FIRST70.csv`, whose own validation split lies inside the
first 70 %), then simulated over the whole record and scored on the last 30 %, which the plant keeps
inside the trained input range (not necessarily on trained hysteresis branches).  Figures are RMSE / noise SD (goal: about 1).

    python experiments/base_fit_independent.py [--quick] [--seeds 1 2]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

import indep_plant  # noqa: E402

import smafl_jax as sj  # noqa: E402
from smafl_jax.report import fit_record  # noqa: E402

RESULTS = ROOT / "experiments" / "results"

#: The record kinds of issue 18's table (drive, rate, start, sensor): the matrix's one definition.
CELLS = indep_plant.MATRIX_CELLS


def run_cell(name, kw, seed, minutes, variants, tmp):
    r = indep_plant.make_record(seed, minutes=minutes, **kw)
    path = tmp / f"rec_{seed}_{kw['drive']}_{kw['start']}_{kw.get('orientation', 'displacement')}.csv"
    indep_plant.write_csv(path, r)
    rec = sj.load_record(path)
    h0, sd = r["heldout_start"], r["noise_sd"]
    # the fit sees only the first 70 % (as a user's file); its own validation split lies inside that part
    train_path = path.with_name(path.stem + "_first70.csv")
    sj.atomic_write_csv(train_path, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
    train_rec = sj.load_record(train_path)
    row = {
        "cell": name,
        "seed": seed,
        "n_samples": len(rec),
        "truth": {
            "hysteresis_input": r["truth"]["hysteresis"]["input"],
            "start": r["truth"]["thermal"]["start"],
            "k1": r["truth"]["thermal"]["k1"],
        },
    }
    for label, opts in variants.items():
        t0 = time.perf_counter()
        model, doc, _ = fit_record(train_rec, **opts)
        yhat = np.asarray(sj.simulate(model, rec.u, rec.dt))  # whole record from t = 0: memory stays continuous
        th = doc["model"].get("thermal", {})
        hy = doc["model"].get("hysteresis", doc["model"])
        row[label] = {
            "train_x_noise": float(np.sqrt(np.mean((yhat[:h0] - rec.y[:h0]) ** 2)) / sd),
            "heldout_x_noise": float(np.sqrt(np.mean((yhat[h0:] - rec.y[h0:]) ** 2)) / sd),
            "seconds": time.perf_counter() - t0,
            "structure": doc["settings"].get("structure"),
            "sees": doc["model"].get("sees"),
            "orientation": hy.get("orientation"),
            "thermal_init": th.get("init"),
            "u0": th.get("u0"),
            "k1": th.get("k1"),
        }
        print(f"{name} seed {seed} [{label}]: train {row[label]['train_x_noise']:.2f}x, held-out {row[label]['heldout_x_noise']:.2f}x "
              f"noise ({row[label]['seconds']:.0f} s)", flush=True)  # fmt: skip
    return row


def markdown(rows, variants, meta):
    lines = [
        "# Default fit on independent records (issue 18)",
        "",
        f"Command: `{meta['command']}`; {meta['minutes']} min records; held-out RMSE / noise SD (goal about 1x).",
        "",
        "| record | seed | truth (hysteresis input, start) | " + " | ".join(f"{v} train | {v} held-out" for v in variants) + " |",
        "| --- | --- | --- | " + " | ".join("--- | ---" for _ in variants) + " |",
    ]
    for r in rows:
        cells = " | ".join(f"{r[v]['train_x_noise']:.2f}x | {r[v]['heldout_x_noise']:.2f}x" for v in variants)
        lines.append(f"| {r['cell']} | {r['seed']} | {r['truth']['hysteresis_input']}, {r['truth']['start']} | {cells} |")
    for v in variants:
        h = [r[v]["heldout_x_noise"] for r in rows]
        lines.append("")
        lines.append(
            f"- {v}: median held-out {np.median(h):.2f}x noise, worst {np.max(h):.2f}x, within 1.2x: {sum(x <= 1.2 for x in h)}/{len(h)}"
        )
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[7])
    ap.add_argument("--minutes", type=float, default=8.0)
    ap.add_argument("--quick", action="store_true", help="defaults only, 4-minute records")
    ap.add_argument("--out", default=str(RESULTS / "base_fit_independent"))
    args = ap.parse_args(argv)
    minutes = 4.0 if args.quick else args.minutes
    variants = {
        "default": {},
        # what `smafl fit` did before this issue: static EUPI, fixed grid, output assumed rising, no refit
        "previous default (EUPI)": dict(model="eupi", thresholds=False, tilts=False, orientation="rises", refit=False),
        # the paper's cascade with the old start rule (at rest with the first input) and no screening
        "paper cascade, steady start": dict(
            model="cascade",
            thresholds=False,
            tilts=False,
            orientation="rises",
            sees="voltage",
            thermal_start="steady",
            refit=False,
        ),
    }
    if not args.quick:
        variants["default, profiled start only"] = {"max_steps": 0}
    tmp = Path("/tmp/smafl_base_fit_independent")
    tmp.mkdir(parents=True, exist_ok=True)
    rows = [run_cell(n, kw, s, minutes, variants, tmp) for s in args.seeds for n, kw in CELLS.items()]
    cmd = "python experiments/base_fit_independent.py " + " ".join(argv if argv is not None else sys.argv[1:])
    meta = {"command": cmd.strip(), "minutes": minutes, "seeds": args.seeds}
    out = Path(args.out)
    sj.atomic_write_json(out.with_suffix(".json"), {**meta, "rows": rows})
    sj.atomic_write_text(out.with_suffix(".md"), markdown(rows, variants, meta))
    print(f"wrote {out.with_suffix('.json')} and {out.with_suffix('.md')}")


if __name__ == "__main__":
    main()
