"""Fit every record (*.csv) in a folder and write one summary table.

    python experiments/fit_folder.py FOLDER --out OUTDIR [any option of smafl fit: --model, --input, --resample, ...]

Each record gets its own sub-folder (fit.json, report.md, figures).  OUTDIR/summary.csv (read it with any CSV
reader) and OUTDIR/summary.md are both rewritten after every record, each atomically (a temporary file in OUTDIR,
then os.replace): a batch stopped by Ctrl-C or a crash keeps the rows of the records done so far, and a finished
batch leaves them complete.  Records that cannot be loaded or fitted are listed with the reason instead of
stopping the batch.  Records of equal length reuse the compiled code.  Progress goes to stderr, one line per record.

Every option but FOLDER and --out is parsed by ``smafl fit``'s own parser and turned into `fit_record` keywords by
`smafl_jax.cli.fit.record_fit_options`, so ``--model cascade`` here fits what ``smafl fit REC.csv --model cascade``
fits (``smafl fit --help`` lists them); the default is ``--model auto`` (every hysteresis
class compared; behind the thermal lag for a drive voltage), with the thresholds and tilts trained as ``smafl
fit`` trains them (``--thresholds`` / ``--tilts``: on for auto, off otherwise).  A rerun into an OUTDIR that
holds results says so, as ``smafl fit`` does (`smafl_jax.prepare_out_dir`), and replaces the files of the same
name; summary.csv is replaced only once the first record of the rerun is done.
"""

from __future__ import annotations

import argparse
import csv
import io
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import smafl_jax as sj
from smafl_jax.cli import build_parser
from smafl_jax.cli.check import apply_window
from smafl_jax.cli.fit import record_fit_options
from smafl_jax.data._data import parse_resample  # private: how smafl fit reads --resample, so the batch reads it alike
from smafl_jax.report import fit_record, write_fit_outputs

COLUMNS = [
    "file",
    "n",
    "model",
    "structure",
    "split",
    "train_rmse",
    "train_e_r_percent",
    "val_rmse",
    "val_e_r_percent",
    "val_max_abs_error",
    "train_over_noise",
    "val_over_noise",
    "noise_sd",
    "k1",
    "converged",
    "seconds",
    "status",
]


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        epilog="Every other option is smafl fit's, with its defaults (smafl fit --help); --window applies to each record.",
    )
    ap.add_argument("folder", help="folder of record CSVs (its *.csv, each fitted on its own)")
    ap.add_argument("--out", required=True, help="output folder: one sub-folder per record, summary.csv, summary.md")
    return ap


def fit_args(rest: list[str]) -> argparse.Namespace:
    """``smafl fit``'s flags (all but the batch's own) parsed by its own parser, on a placeholder record."""
    return build_parser("fit").parse_args(["fit", "record.csv", *rest])


def fit_options(args: argparse.Namespace) -> dict:
    """The keywords ``smafl fit`` passes to `fit_record` for the same flags (without its progress lines)."""
    return record_fit_options(args, progress=False)


def _num(x, fmt: str) -> str:
    return "" if x is None else format(float(x), fmt)


def summary_row(path: Path, rec, model, doc: dict, seconds: float) -> dict:
    """One summary row of a fitted record (fit.json ``doc``)."""
    tr, va = doc["metrics"]["train"], doc["metrics"]["validation"] or {}
    noise = doc["metrics"].get("noise") or {}
    thermal = sj.thermal_of(model)
    k1 = getattr(thermal, "k1", None)
    return dict(
        file=path.name,
        n=len(rec),
        model=doc["settings"].get("model", ""),
        structure=doc["settings"].get("structure", ""),
        split=doc["split"]["kind"],
        train_rmse=_num(tr.get("rmse"), ".6g"),
        train_e_r_percent=_num(tr.get("e_r_percent"), ".4g"),
        val_rmse=_num(va.get("rmse"), ".6g"),
        val_e_r_percent=_num(va.get("e_r_percent"), ".4g"),
        val_max_abs_error=_num(va.get("max_abs_error"), ".6g"),
        train_over_noise=_num(noise.get("train_ratio"), ".4g"),
        val_over_noise=_num(noise.get("validation_ratio"), ".4g"),
        noise_sd=_num(noise.get("sd"), ".4g"),
        k1=_num(None if k1 is None else np.ravel(np.asarray(k1))[0], ".6g"),
        converged=doc["solver"]["converged"],
        seconds=f"{seconds:.1f}",
        status="ok" if doc["solver"]["converged"] else doc["solver"]["message"],
    )


def write_summary(out: Path, rows: list[dict]) -> None:
    """summary.csv (the `csv` module quotes what needs it) and summary.md, each written atomically."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    sj.atomic_write_text(out / "summary.csv", buf.getvalue())
    md = ["| " + " | ".join(COLUMNS) + " |", "|" + " --- |" * len(COLUMNS)]
    md += ["| " + " | ".join(str(r[c]).replace("|", "/").replace("\n", " ") for c in COLUMNS) + " |" for r in rows]
    sj.atomic_write_text(out / "summary.md", "\n".join(md) + "\n")


def main(argv=None) -> int:
    args, rest = parser().parse_known_args(argv)
    fit = fit_args(rest)
    files = sorted(Path(args.folder).glob("*.csv"))
    if not files:
        print(f"error: no *.csv files in {args.folder}", file=sys.stderr)
        return 2
    try:
        out = sj.prepare_out_dir(args.out)  # says so when OUTDIR holds earlier results, as `smafl fit` does
    except sj.UserInputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    try:
        options = fit_options(fit)
    except sj.UserInputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    rows: list[dict] = []
    t0 = time.perf_counter()
    for i, path in enumerate(files):
        row = dict.fromkeys(COLUMNS, "")
        row.update(file=path.name, model=fit.model)
        t1 = time.perf_counter()
        try:
            rec = sj.load_record(path, input=fit.input, output=fit.output, time=fit.time, resample=parse_resample(fit.resample))
            (rec,) = apply_window([rec], fit.window)
            model, doc, masks = fit_record(rec, **options)
            write_fit_outputs(out / path.stem, rec, doc, masks, figures=not fit.no_figures)
            row = summary_row(path, rec, model, doc, time.perf_counter() - t1)
        except sj.UserInputError as exc:  # DataError is a UserInputError
            row["status"] = f"failed: {exc}"
        except KeyboardInterrupt:
            print(
                f"interrupted during {path.name} ({i + 1}/{len(files)}); {out / 'summary.csv'} holds the {len(rows)} "
                "record(s) done before it",
                file=sys.stderr,
            )
            return 130
        rows.append(row)
        write_summary(out, rows)  # after every record: an interrupted batch keeps what is done
        ratio = f", held out {row['val_over_noise']}x noise" if row["val_over_noise"] else ""
        print(
            f"[{i + 1}/{len(files)}] {path.name}: {row['status']}{ratio} ({time.perf_counter() - t1:.1f} s, "
            f"{time.perf_counter() - t0:.0f} s elapsed)",
            file=sys.stderr,
        )
    print(f"wrote {out / 'summary.csv'} and {out / 'summary.md'} ({len(rows)} records)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
