"""Issue 18 / 14: which hysteresis class should `smafl fit REC` (no --model) use when the input is measured directly?

Records from tests/indep_direct.py (plain numpy, no smafl_jax import: play operators with their own envelopes,
a continuous Preisach density, a Bouc-Wen model), the input a temperature-like column (not a drive voltage).
Per plant seed: a training record with one drive family and a second run of the SAME plant with another family.
Each candidate class (`fit_record(model=...)` with its defaults: EUPI with trained thresholds and tilts as
``--model auto`` fits it today, and Preisach) is fitted on the first record; its validation error there
(last 30 %) is what a choice rule can see, the second run (the saved model simulated with `simulate_record`,
initial state from the fit) is what a user gets.  ``auto`` is whatever `fit_record(model="auto")` picks.

    OPENBLAS_NUM_THREADS=1 python experiments/structure_choice_direct.py OUT.jsonl SEED [SEED ...] [--plants play,preisach]
        [--candidates auto,eupi_auto,preisach]
    python experiments/structure_choice_direct.py --table OUT.jsonl
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
import indep_direct as ind  # noqa: E402

CANDIDATES = ("auto", "eupi_auto", "preisach")
DRIVE_PAIRS = (("forc", "levels"), ("levels", "triangles"), ("triangles", "sines"), ("sines", "steps"), ("steps", "forc"))


def run_one(seed: int, plant: str, out_rows: list, fh, candidates=CANDIDATES) -> None:
    import smafl_jax as sj
    from smafl_jax.report import fit_record, write_fit_outputs
    from smafl_jax.workflows.simulate import simulate_record

    d_train, d_test = DRIVE_PAIRS[seed % len(DRIVE_PAIRS)]
    orientation = -1 if seed % 3 == 2 else 1
    a = ind.make_record(seed, plant, d_train, orientation=orientation)
    b = ind.make_record(seed + 1000, plant, d_test, truth=a["truth"])
    sd = a["noise_sd"]
    with tempfile.TemporaryDirectory() as tmp:
        pa, pb = Path(tmp) / "a.csv", Path(tmp) / "b.csv"
        ind.write_csv(pa, a)
        ind.write_csv(pb, b)
        rec = sj.load_record(pa, input="temperature_C", output="length_mm")
        for cand in candidates:
            kw = {"model": "auto"} if cand == "auto" else {"model": "eupi", "thresholds": True, "tilts": True}
            if cand == "preisach":
                kw = {"model": "preisach"}
            t0 = time.perf_counter()
            _, doc, masks = fit_record(rec, **kw)
            seconds = time.perf_counter() - t0
            out = Path(tmp) / f"fit_{cand}"
            out.mkdir()
            write_fit_outputs(out, rec, doc, masks, figures=False)
            sim = simulate_record(out / "fit.json", pb)
            v = doc["metrics"]["validation"]
            row = {
                "plant": plant,
                "seed": seed,
                "drives": [d_train, d_test],
                "orientation": orientation,
                "candidate": cand,
                "structure": doc["settings"]["structure"],
                "val_over_noise": v["rmse"] / sd,
                "val_e_r": v["e_r_percent"],
                "second_run_over_noise": sim.scores["rmse"] / sd,
                "second_run_e_r": sim.scores["e_r_percent"],
                "seconds": seconds,
                "choice": doc["settings"].get("structure_choice"),
            }
            out_rows.append(row)
            fh.write(json.dumps(row) + "\n")
            fh.flush()
            print(
                f"{plant} s{seed} {cand}: {row['structure']} val {row['val_over_noise']:.2f}x, second run "
                f"{row['second_run_over_noise']:.2f}x (e_r {row['second_run_e_r']:.1f} %), {seconds:.0f} s",
                flush=True,
            )


def table(paths: list[str]) -> None:
    rows = [json.loads(line) for p in paths for line in open(p) if line.strip()]
    keys = sorted({(r["plant"], r["seed"]) for r in rows})
    print("| plant | seed | drives | " + " | ".join(f"{c}: val / 2nd run (x noise), e_r 2nd" for c in CANDIDATES) + " |")
    print("|---|---|---|" + "---|" * len(CANDIDATES))
    for k in keys:
        got = {r["candidate"]: r for r in rows if (r["plant"], r["seed"]) == k}
        cells = []
        for c in CANDIDATES:
            r = got.get(c)
            cells.append(
                "-"
                if r is None
                else f"{r['structure']} {r['val_over_noise']:.2f} / {r['second_run_over_noise']:.2f}, {r['second_run_e_r']:.1f} %"
            )
        d = next(iter(got.values()))
        print(f"| {k[0]} | {k[1]} | {'->'.join(d['drives'])} | " + " | ".join(cells) + " |")
    for c in CANDIDATES:
        v = [r["second_run_over_noise"] for r in rows if r["candidate"] == c]
        if v:
            print(f"{c}: second run geometric mean {np.exp(np.mean(np.log(v))):.2f}x noise over {len(v)} records")
    # the rule `--model auto` applies, from the two single-class rows: the lower validation RMSE is kept
    picked, right = [], 0
    for k in keys:
        got = {r["candidate"]: r for r in rows if (r["plant"], r["seed"]) == k}
        if "eupi_auto" in got and "preisach" in got:
            pick = min((got["eupi_auto"], got["preisach"]), key=lambda r: r["val_over_noise"])
            best = min((got["eupi_auto"], got["preisach"]), key=lambda r: r["second_run_over_noise"])
            picked.append(pick["second_run_over_noise"])
            right += pick is best
    if picked:
        print(
            f"validation choice (the auto rule, from the single-class rows): second run geometric mean "
            f"{np.exp(np.mean(np.log(picked))):.2f}x noise; it picked the class better on the second run for {right}/{len(picked)}"
        )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("seeds", nargs="*", type=int)
    ap.add_argument("--plants", default=",".join(ind.PLANTS))
    ap.add_argument("--candidates", default=",".join(CANDIDATES))
    ap.add_argument("--table", action="store_true")
    a = ap.parse_args()
    if a.table:
        table([a.out])
        return
    rows: list = []
    with open(a.out, "a") as fh:
        for seed in a.seeds:
            for plant in a.plants.split(","):
                run_one(seed, plant, rows, fh, a.candidates.split(","))


if __name__ == "__main__":
    main()
