"""Held-out coverage of `smafl sample`'s predictive bands on independent records (the sampler's gain prior).

Each record comes from tests/indep_plant.py (plain numpy, no smafl_jax import).  The user's route, through the CLI:
`smafl fit` on the first 70 % of the record, then `smafl sample RECORD --fit fit.json --holdout-fraction 0.3` on the
whole record, so the sampled part is exactly the fit's training part and the last 30 % is predicted.  Every variant of
the sampler's settings (``--gain-scale`` given in units of the training output range, or the default) samples the same
fit.  Per record and variant: the held-out 95 % coverage of the predictive band (nominal 0.95), the median band
half-width and the RMSE of the band's median over the held-out samples, both in noise SDs.

    python experiments/heldout_coverage.py OUT --seeds 13 17 --steps 400 --variants default 1
    python experiments/heldout_coverage.py OUT --table

Rows are appended to OUT/rows.jsonl as each finishes (a rerun skips the rows already there).
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

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
import indep_plant as ip  # noqa: E402  (plain numpy: no smafl_jax import)


def _cli(*args: str) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    got = subprocess.run([sys.executable, "-m", "smafl_jax.cli", *args], cwd=ROOT, env=env, capture_output=True, text=True)
    if got.returncode != 0:
        raise RuntimeError(f"smafl {' '.join(args[:2])} failed:\n{got.stderr[-3000:]}")


def _write(path: Path, time_s, u, y) -> None:
    tmp = path.with_suffix(".tmp")
    np.savetxt(tmp, np.column_stack([time_s, u, y]), delimiter=",", header="time_s,voltage_V,displacement_mm", comments="")
    os.replace(tmp, path)


def run_record(out: Path, cell: str, seed: int, minutes: float, steps: int, variants: list[str], done: set) -> list[dict]:
    kw = ip.MATRIX_CELLS[cell]
    r = ip.make_record(seed, minutes=minutes, **kw)
    tag = f"s{seed}_{kw['drive']}_{kw['start']}_{kw.get('orientation', 'displacement')}_{int(kw['rate_hz'])}hz"
    work = out / tag
    work.mkdir(parents=True, exist_ok=True)
    h0, sd = r["heldout_start"], r["noise_sd"]
    full, part = work / "record.csv", work / "train70.csv"
    _write(full, r["time"], r["u"], r["y"])
    _write(part, r["time"][:h0], r["u"][:h0], r["y"][:h0])
    fit_dir = work / "fit"
    t0 = time.time()
    if not (fit_dir / "fit.json").exists():
        _cli("fit", str(part), "--out", str(fit_dir), "--no-figures")
    fit_s = time.time() - t0
    y_range = float(np.ptp(r["y"][:h0]))
    import smafl_jax as sj  # only to score the fit itself (the records above are made without it)

    fitted, _ = sj.load_model_file(fit_dir / "fit.json")
    e_fit = np.asarray(sj.simulate(fitted, r["u"], r["dt"])) - r["y"]
    fit_held = float(np.sqrt(np.mean(e_fit[h0:] ** 2)) / sd)
    rows = []
    for v in variants:
        if (cell, seed, v) in done:
            continue
        s_dir = work / f"sample_{v}"
        extra = [] if v == "default" else ["--gain-scale", f"{float(v) * y_range:.10g}"]
        t1 = time.time()
        _cli(
            "sample", str(full), "--fit", str(fit_dir / "fit.json"), "--out", str(s_dir), "--steps", str(steps),
            "--holdout-fraction", str(ip.HELDOUT_FRACTION), "--no-progress", "--restart", *extra,
        )  # fmt: skip
        summary = json.loads((s_dir / "summary.json").read_text())
        pred = np.genfromtxt(s_dir / "predictive.csv", delimiter=",", names=True)
        held = pred["heldout"] > 0
        y = r["y"][-int(held.sum()) :] if held.sum() else np.zeros(0)
        half = 0.5 * (pred["pred_q975"][held] - pred["pred_q025"][held])
        rows.append(
            {
                "cell": cell,
                "seed": seed,
                "variant": v,
                "gain_scale": summary.get("settings", {}).get("gain_scale", summary.get("gain_scale")),
                "coverage95": summary.get("heldout_coverage_95"),
                "heldout_samples": int(held.sum()),
                "fit_heldout_noise": fit_held,
                "median_rmse_noise": float(np.sqrt(np.mean((pred["median"][held] - y) ** 2)) / sd),
                "band_halfwidth_noise": float(np.median(half) / sd),
                "warnings": len(summary.get("warnings", [])),
                "fit_s": fit_s,
                "sample_s": time.time() - t1,
            }
        )
        print(json.dumps(rows[-1]), flush=True)
        with open(out / "rows.jsonl", "a") as f:
            f.write(json.dumps(rows[-1]) + "\n")
    return rows


def table(out: Path) -> None:
    rows = [json.loads(line) for line in (out / "rows.jsonl").read_text().splitlines() if line.strip()]
    variants = sorted({r["variant"] for r in rows}, key=lambda v: (v != "default", v))
    print("| record | seed | " + " | ".join(f"{v}: coverage / median RMSE / band half-width" for v in variants) + " |")
    print("| --- | --- | " + " | ".join("---" for _ in variants) + " |")
    keys = sorted({(r["cell"], r["seed"]) for r in rows}, key=lambda k: (k[1], k[0]))
    by = {(r["cell"], r["seed"], r["variant"]): r for r in rows}
    for cell, seed in keys:
        cells = []
        for v in variants:
            r = by.get((cell, seed, v))
            cells.append(
                "-" if r is None else f"{r['coverage95']:.3f} / {r['median_rmse_noise']:.2f}x / {r['band_halfwidth_noise']:.2f}x"
            )
        print(f"| {cell} | {seed} | " + " | ".join(cells) + " |")
    for v in variants:
        rs = [r for r in rows if r["variant"] == v and r["coverage95"] is not None]
        cov = np.array([r["coverage95"] for r in rs])
        print(
            f"\n- {v}: {len(rs)} records, held-out 95 % coverage median {np.median(cov):.3f}, "
            f"records in [0.90, 0.99]: {int(np.sum((cov >= 0.9) & (cov <= 0.99)))}, below 0.90: {int(np.sum(cov < 0.9))}, "
            f"above 0.99: {int(np.sum(cov > 0.99))}; median band half-width "
            f"{np.median([r['band_halfwidth_noise'] for r in rs]):.2f}x noise"
        )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out", type=Path)
    p.add_argument("--seeds", type=int, nargs="*", default=[13, 17])
    p.add_argument("--cells", nargs="*", default=None, help="cell names of tests/indep_plant.MATRIX_CELLS (default all)")
    p.add_argument("--minutes", type=float, default=10.0)
    p.add_argument("--steps", type=int, default=400)
    p.add_argument("--variants", nargs="*", default=["default", "1"], help="'default' or a gain scale in output ranges")
    p.add_argument("--table", action="store_true")
    a = p.parse_args()
    if a.table:
        table(a.out)
        return
    a.out.mkdir(parents=True, exist_ok=True)
    rows_file = a.out / "rows.jsonl"
    done = set()
    if rows_file.exists():
        done = {(r["cell"], r["seed"], r["variant"]) for r in map(json.loads, rows_file.read_text().splitlines()) if r}
    for seed in a.seeds:
        for cell in a.cells or list(ip.MATRIX_CELLS):
            run_record(a.out, cell, seed, a.minutes, a.steps, a.variants, done)


if __name__ == "__main__":
    main()
