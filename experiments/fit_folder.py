"""Fit every record (*.csv) in a folder and write one summary table.

    python experiments/fit_folder.py FOLDER --out OUTDIR [--model auto] [--input COL --output COL --split auto]

Each record gets its own sub-folder (fit.json, report.md, figures).  OUTDIR/summary.csv (read it with any CSV
reader) and OUTDIR/summary.md are both rewritten after every record, each atomically (a temporary file in OUTDIR,
then os.replace): a batch stopped by Ctrl-C or a crash keeps the rows of the records done so far, and a finished
batch leaves them complete.  Records that cannot be loaded or fitted are listed with the reason instead of
stopping the batch.  Records of equal length reuse the compiled code.  Progress goes to stderr, one line per record.

The fit options and their defaults are those of ``smafl fit`` (read from its parser), so ``--model cascade``
here fits what ``smafl fit REC.csv --model cascade`` fits; the default is ``--model auto`` (every hysteresis
class compared; behind the thermal lag for a drive voltage), with the thresholds and tilts trained as ``smafl
fit`` trains them (``--thresholds`` / ``--tilts``: on for auto, off otherwise).  A rerun into an OUTDIR that
holds results says so, as ``smafl fit`` does (`smafl_jax.prepare_out_dir`), and replaces the files of the same
name; summary.csv is replaced only once the first record of the rerun is done.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import smafl_jax as sj
from smafl_jax._choices import MEMORY, SPLITS  # private: the option lists of `smafl fit`, so the flags match it
from smafl_jax.cli import build_parser
from smafl_jax.report import MODELS, fit_record, write_fit_outputs

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

#: ``smafl fit``'s defaults (its parser on a placeholder record): one source for the flags below.
CLI_DEFAULTS = vars(build_parser("fit").parse_args(["fit", "record.csv"]))


def _gain_prior(text: str) -> float | None:
    """``--gain-prior``: a number > 0, or none (as ``smafl fit`` reads it)."""
    if text.strip().lower() == "none":
        return None
    try:
        kappa = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number > 0 or 'none', got {text!r}") from None
    if not (math.isfinite(kappa) and kappa > 0):
        raise argparse.ArgumentTypeError(f"expected a number > 0 or 'none', got {text!r}")
    return kappa


def _resample(text: str) -> float | str:
    return text if text == "auto" else float(text)


def parser() -> argparse.ArgumentParser:
    d = CLI_DEFAULTS
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", help="folder of record CSVs (its *.csv, each fitted on its own)")
    ap.add_argument("--out", required=True, help="output folder: one sub-folder per record, summary.csv, summary.md")
    ap.add_argument("--input", default=None, help="input column (default: as smafl fit finds it)")
    ap.add_argument("--output", default=None, help="output column (default: as smafl fit finds it)")
    ap.add_argument("--time", default=None, metavar="COL", help="time column (default: as smafl fit finds it)")
    ap.add_argument("--resample", type=_resample, default=None, metavar="DT|auto", help="as smafl fit --resample")
    ap.add_argument("--model", choices=MODELS, default=d["model"], help=f"as smafl fit --model (default {d['model']})")
    ap.add_argument("--split", choices=SPLITS, default=d["split"], help=f"as smafl fit (default {d['split']})")
    ap.add_argument("--val-fraction", type=float, default=d["val_fraction"], help=f"default {d['val_fraction']}")
    ap.add_argument("--solver", choices=sj.SOLVERS, default=d["solver"], help=f"default {d['solver']}")
    ap.add_argument("--max-steps", type=int, default=d["max_steps"], help=f"default {d['max_steps']}")
    for flag in ("thresholds", "tilts"):
        ap.add_argument(
            f"--{flag}",
            action=argparse.BooleanOptionalAction,
            default=d[flag],
            help=f"train the {flag} (default: as smafl fit, on for --model auto, off otherwise)",
        )
    ap.add_argument("--memory", choices=MEMORY, default=d["memory"], help=f"default {d['memory']}")
    starts = {"orientation": ("auto", "rises", "falls"), "thermal_start": ("auto", "steady", "cold", "fitted")}
    for flag, choices in {**starts, "sees": ("auto", "voltage", "heat")}.items():  # smafl fit's choices
        ap.add_argument(f"--{flag.replace('_', '-')}", choices=choices, default=d[flag], help=f"as smafl fit (default {d[flag]})")
    ap.add_argument("--gain-prior", type=_gain_prior, default=d["gain_prior"], metavar="KAPPA", help="as smafl fit")
    for flag in ("n_sym", "n_alpha", "n_asym", "poly_order"):
        ap.add_argument(f"--{flag.replace('_', '-')}", type=int, default=d[flag], help=f"default {d[flag]}")
    ap.add_argument("--no-refit", action="store_true", help="as smafl fit --no-refit")
    ap.add_argument("--early-stopping", action="store_true", help="as smafl fit --early-stopping")
    ap.add_argument("--no-figures", action="store_true")
    return ap


def fit_options(args: argparse.Namespace) -> dict:
    """The keywords ``smafl fit`` passes to `fit_record` for the same flags (without its progress lines)."""
    return dict(
        model=args.model,
        split=args.split,
        val_fraction=args.val_fraction,
        solver=args.solver,
        max_steps=args.max_steps,
        thresholds=args.thresholds,
        tilts=args.tilts,
        orientation=args.orientation,
        thermal_start=args.thermal_start,
        sees=args.sees,
        memory=args.memory,
        refit=not args.no_refit,
        gain_prior=args.gain_prior,
        early_stopping=args.early_stopping,
        grid=dict(n_sym=args.n_sym, n_alpha=args.n_alpha, n_asym=args.n_asym, poly_order=args.poly_order),
    )


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
    args = parser().parse_args(argv)
    files = sorted(Path(args.folder).glob("*.csv"))
    if not files:
        print(f"error: no *.csv files in {args.folder}", file=sys.stderr)
        return 2
    try:
        out = sj.prepare_out_dir(args.out)  # says so when OUTDIR holds earlier results, as `smafl fit` does
    except sj.UserInputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    options = fit_options(args)
    rows: list[dict] = []
    t0 = time.perf_counter()
    for i, path in enumerate(files):
        row = dict.fromkeys(COLUMNS, "")
        row.update(file=path.name, model=args.model)
        t1 = time.perf_counter()
        try:
            rec = sj.load_record(path, input=args.input, output=args.output, time=args.time, resample=args.resample)
            model, doc, masks = fit_record(rec, **options)
            write_fit_outputs(out / path.stem, rec, doc, masks, figures=not args.no_figures)
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
