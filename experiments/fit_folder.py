"""Fit every record (*.csv) in a folder and write one summary table.

    python experiments/fit_folder.py FOLDER --model eupi --out OUTDIR [--input COL --output COL --split auto]

Each record gets its own sub-folder (fit.json, report.md, figures) and the
summary goes to OUTDIR/summary.csv and OUTDIR/summary.md.  Records that cannot
be loaded or fitted are listed with the reason instead of stopping the batch.
Records of equal length reuse the compiled code.  Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import smafl_jax as sj
from smafl_jax.report import MODELS, fit_record, write_fit_outputs

COLUMNS = [
    "file",
    "n",
    "model",
    "split",
    "train_rmse",
    "train_e_r_percent",
    "val_rmse",
    "val_e_r_percent",
    "val_max_abs_error",
    "k1",
    "converged",
    "seconds",
    "status",
]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder")
    ap.add_argument("--model", choices=MODELS, default="eupi")
    ap.add_argument("--out", required=True)
    ap.add_argument("--input", default=None)
    ap.add_argument("--output", default=None)
    ap.add_argument("--split", default="auto")
    ap.add_argument("--max-steps", type=int, default=300)
    ap.add_argument("--no-figures", action="store_true")
    args = ap.parse_args(argv)
    files = sorted(Path(args.folder).glob("*.csv"))
    if not files:
        print(f"error: no *.csv files in {args.folder}", file=sys.stderr)
        return 2
    out = sj.prepare_out_dir(args.out)
    rows = []
    t0 = time.perf_counter()
    for i, path in enumerate(files):
        row = dict.fromkeys(COLUMNS, "")
        row.update(file=path.name, model=args.model)
        try:
            rec = sj.load_record(path, input=args.input, output=args.output)
            t1 = time.perf_counter()
            model, doc, masks = fit_record(rec, model=args.model, split=args.split, max_steps=args.max_steps)
            write_fit_outputs(out / path.stem, rec, doc, masks, figures=not args.no_figures)
            tr, va = doc["metrics"]["train"], doc["metrics"]["validation"] or {}
            row.update(
                n=len(rec),
                split=doc["split"]["kind"],
                train_rmse=f"{tr['rmse']:.6g}",
                train_e_r_percent=f"{tr['e_r_percent']:.4g}",
                val_rmse=f"{va['rmse']:.6g}" if va else "",
                val_e_r_percent=f"{va['e_r_percent']:.4g}" if va else "",
                val_max_abs_error=f"{va['max_abs_error']:.6g}" if va else "",
                k1=f"{float(model.thermal.k1):.6g}" if hasattr(model, "thermal") else "",
                converged=doc["solver"]["converged"],
                seconds=f"{time.perf_counter() - t1:.1f}",
                status="ok" if doc["solver"]["converged"] else doc["solver"]["message"],
            )
        except sj.UserInputError as exc:  # DataError is a UserInputError
            row["status"] = f"failed: {exc}"
        rows.append(row)
        print(f"[{i + 1}/{len(files)}] {path.name}: {row['status']} ({time.perf_counter() - t0:.0f} s elapsed)", file=sys.stderr)
    sj.atomic_write_text(
        out / "summary.csv",
        ",".join(COLUMNS)
        + "\n"
        + "".join(",".join(f'"{r[c]}"' if "," in str(r[c]) else str(r[c]) for c in COLUMNS) + "\n" for r in rows),
    )
    md = ["| " + " | ".join(COLUMNS) + " |", "|" + " --- |" * len(COLUMNS)]
    md += ["| " + " | ".join(str(r[c]).replace("|", "/") for c in COLUMNS) + " |" for r in rows]
    sj.atomic_write_text(out / "summary.md", "\n".join(md) + "\n")
    print(f"wrote {out / 'summary.csv'} and {out / 'summary.md'} ({len(rows)} records)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
