"""``smafl fit DATA.csv [--model auto|eupi|cascade|joule] --out DIR``: identify a model from one record.

Writes ``fit.json`` (model, train/validation metrics, data hash, settings,
versions), ``report.md`` and figures into DIR.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from .._choices import GAIN_PRIOR, HOLD_INPUT, SLOW_MODES
from .check import TIME_HELP, add_resample_argument, add_window_argument, apply_window


def add_parser(sub):
    from .._choices import HYSTERESIS, MEMORY, MODELS, SOLVERS, SPLITS

    p = sub.add_parser("fit", help="fit a model to a record: fit.json, report.md and figures")
    p.add_argument(
        "data",
        nargs="+",
        help="record CSV (time_s, input and output columns; optional branch column); several files, a folder (its *.csv) "
        "or a glob fit ONE joint model (each record from its own initial state) with leave-one-record-out validation "
        "(--split none skips it)",
    )
    add_resample_argument(p)
    p.add_argument("--input", default=None, help="input column (default: sidecar, else a common name such as voltage_V)")
    p.add_argument("--output", default=None, help="output column (default: sidecar, else e.g. displacement_mm)")
    p.add_argument("--time", default=None, metavar="COL", help=TIME_HELP)
    add_window_argument(p)
    p.add_argument(
        "--model",
        choices=MODELS,
        default="auto",
        help="auto (every hysteresis class fitted and the lower validation RMSE kept: behind the thermal lag for a drive "
        "voltage (cascade and the other classes that auto compares behind the lag, README: Model choice; the EUPI "
        "cascade stays unless a class with a lower "
        "validation RMSE halves it or fits the training part better), on the input itself for any other input "
        f"({', '.join(HYSTERESIS)}); thresholds and tilts trained), eupi (paper eq. 2), cascade (thermal + EUPI), "
        "cascade-NAME (thermal + another registered hysteresis model), joule (eq. 7 lag), or any registered "
        f"hysteresis model alone ({', '.join(HYSTERESIS)}); default auto",
    )
    p.add_argument("--out", default=None, help="output folder (default: fit_<data stem>)")
    p.add_argument(
        "--split",
        choices=SPLITS,
        default="auto",
        help="validation split: branch (every 3rd branch), time (last part), interleaved (every 3rd of 10 blocks, not "
        "the first: for a record whose last part leaves the levels the first part visited), none; auto = branch if a "
        "'branch' column exists, else time",
    )
    p.add_argument(
        "--val-fraction", type=float, default=0.3, help="held-out fraction for the time or interleaved split (default 0.3)"
    )
    p.add_argument(
        "--solver",
        choices=SOLVERS,
        default="lm",
        help="joint refinement solver (default lm); varpro: LM over thresholds, tilts, thermal rate and start with the gains "
        "solved exactly at every step (lower training error, held-out error better on 10 and worse on 5 of 30 "
        "independent records; docs/identification.md)",
    )
    p.add_argument("--max-steps", type=int, default=300, help="refinement steps (0 = initialiser only)")
    p.add_argument(
        "--thresholds",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="train the play thresholds (default: on for --model auto, off otherwise)",
    )
    p.add_argument(
        "--tilts",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="train the unparallel tilts (default: on for --model auto, off otherwise)",
    )
    p.add_argument(
        "--orientation",
        choices=("auto", "rises", "falls"),
        default="auto",
        help="does the output rise or fall when the actuator contracts (length sensors fall); default: screened",
    )
    p.add_argument(
        "--no-refit",
        action="store_true",
        help="one record: save the model fitted on the training samples instead of refitting the chosen structure on the whole record",
    )
    p.add_argument(
        "--sees",
        choices=("auto", "voltage", "heat"),
        default="auto",
        help="cascade: the hysteresis acts on the effective voltage (paper) or on the heat / temperature rise (V^2); "
        "default: screened",
    )
    p.add_argument(
        "--thermal-start",
        choices=("auto", "steady", "cold", "fitted"),
        default="auto",
        help="cascade thermal state at t=0: steady (at rest with the first input), cold, or fitted (auto: screened, then fitted)",
    )
    p.add_argument(
        "--memory",
        choices=MEMORY,
        default="auto",
        help="operators' state at t=0: fitted (each operator's place between its bounds is trained; one record), "
        "rule (the best of the rules descended, zero and from_top on the training samples), or one of those rules, "
        "or auto (rule and fitted both refined, the validation samples choose); with --model auto a named rule fits "
        "only the classes that have it (from_top: the EUPI)",
    )
    p.add_argument(
        "--gain-prior",
        type=_gain_prior_arg,
        default=GAIN_PRIOR,
        metavar="KAPPA",
        help=f"prior on each operator gain: N(0, (KAPPA x output range)^2), the gains are its MAP (default {GAIN_PRIOR:g}; "
        "'none': plain least squares). Keeps near-constant operators from cancelling the offset with huge gains that "
        "break on a new run",
    )
    p.add_argument(
        "--early-stopping",
        action="store_true",
        help="stop the split fit's joint refinement when 2 chunks of 50 steps in a row do not lower the validation error, "
        "and keep its best iterate (one record; off by default: on fresh independent records it helped --model auto and "
        "cut the fit time by about a sixth, but made some single-class fits worse; docs/identification.md, session 23)",
    )
    p.add_argument(
        "--median",
        action="store_true",
        help="with --model auto on one record: also write median_fit.json, the sample-by-sample median of every class "
        "compared, each refitted on the whole record (one refit more per class; on 60 independent records it held out "
        "0.88x the geometric-mean error of the class the validation block keeps, but not on every kind of record; "
        "docs/identification.md, session 28)",
    )
    p.add_argument(
        "--sparse-grid",
        action="store_true",
        help="with --model auto on a drive voltage: also fit the EUPI cascade on a sparse grid (4 + 2 x 2 operators) and let "
        "the validation error choose (off by default: on one independent plant the held-out geometric mean went 2.67x -> "
        "2.11x the noise, on another it made an excursion record 10x worse; docs/identification.md, session 43)",
    )
    p.add_argument(
        "--hold-input",
        choices=HOLD_INPUT,
        default="auto",
        help="the saved model's hysteresis holds its input to the trained range, so that it does not extrapolate outside "
        "it: 'auto' (default) a directly measured input (temperature, pressure), unless the validation samples beyond the "
        "training range are predicted better extrapolating, and a cascade's thermal state on its cold side only; 'on' "
        "both sides always; 'off' never (fit.json settings.hold_input; NiTi runs past the trained temperatures 18.2 -> "
        "3.9 and 9.2 -> 1.2; a thermal state held above its range on simulated plants worse, below it better on the whole)",
    )
    p.add_argument(
        "--slow-mode",
        choices=SLOW_MODES,
        default="auto",
        help="a second, slower thermal mode in a cascade (a wire on a nylon line, in a sleeve or on clamps warms a second "
        "mass): 'auto' (default, one record with --model auto) fits every compared class again with one (from a fresh "
        "start and from its one-mode fit) when the kept whole-record fit leaves more than 2x the noise, and keeps the best "
        "when it is lower on validation by more than 1.2x and lower on the whole record; 'on': every cascade gets one; "
        "'off': never (fit.json settings.structure_choice.slow_mode_check)",
    )
    p.add_argument("--n-sym", type=int, default=8, help="symmetric play operators (default 8)")
    p.add_argument("--n-alpha", type=int, default=4, help="tilts of unparallel operators (default 4)")
    p.add_argument("--n-asym", type=int, default=4, help="thresholds per tilt (default 4)")
    p.add_argument("--poly-order", type=int, default=3, help="polynomial order (default 3, as in the paper)")
    p.add_argument("--no-figures", action="store_true", help="skip the figures")
    p.set_defaults(func=run)
    return p


def run(args):
    from .. import prepare_out_dir
    from .._errors import UserInputError
    from ..data import load_records
    from ..data._data import parse_resample
    from ..identify._metrics import ABOVE_NOISE
    from ..report._report_fit import BRANCHES_OPEN, STATIC_ON_DRIVE, fit_record, write_fit_outputs

    options = record_fit_options(args)  # checks the flags before anything is read
    records = load_records(args.data, args.input, args.output, time=args.time, resample=parse_resample(args.resample))
    records = apply_window(records, args.window)
    note = _accelerator_note()
    if note:
        print(note, file=sys.stderr)
    import numpy as np

    from .._io import check_record_magnitude

    for r in records:
        check_record_magnitude(r)  # values whose squares overflow: refuse before any work (issue 16)
        if r.y is not None and len(r.y) and float(np.ptp(r.y)) == 0.0:
            raise UserInputError(
                f"{r.path}, column '{r.output_name}': the output is constant ({float(r.y[0]):g}): there is nothing to "
                "identify, and e_r (eq. 3, relative to the output range) is undefined"
            )
        for note in r.processing:
            print(f"loading {r.name}: {note}", file=sys.stderr)
    if len(records) > 1:
        return _run_records(args, records, options["grid"])
    rec = records[0]
    started = time.time()  # files in the folder older than this are an earlier run's (`leftovers_note`)
    out = prepare_out_dir(args.out or f"fit_{Path(rec.path).stem}")
    print(f"fitting {args.model} to {rec.path} ({len(rec)} samples, {rec.input_name} -> {rec.output_name})", file=sys.stderr)
    model, doc, masks = fit_record(rec, **options)
    import math

    if doc["settings"].get("structure_choice"):  # model auto compared classes: say which won and on what
        print(doc["notes"][0], file=sys.stderr)
    for note in doc["notes"]:
        if note.startswith((STATIC_ON_DRIVE, ABOVE_NOISE, BRANCHES_OPEN)):
            print(f"warning: {note}", file=sys.stderr)
    train_rmse = doc["metrics"]["train"].get("rmse")
    if train_rmse is None or not math.isfinite(float(train_rmse)):  # never report a non-finite fit as a success
        raise UserInputError(f"{rec.path}: the fit has a non-finite training RMSE; nothing written (check the data's scale)")
    doc = write_fit_outputs(out, rec, doc, masks, figures=not args.no_figures)
    sv = doc["solver"]
    if not sv["converged"]:
        # name the class: with --model auto several were refined, and the message is the kept one's (trial 7 read it
        # as a failure of the whole fit)
        print(f"warning: {doc['settings'].get('structure', args.model)}: {sv['message']}", file=sys.stderr)
    tr, va = doc["metrics"]["train"], doc["metrics"]["validation"]
    noise = doc["metrics"].get("noise") or {}
    line = f"train rmse {tr['rmse']:.4g}{_in_noise(noise, 'train')}, e_r {tr['e_r_percent']:.3g} %"
    if va:
        line += f"; validation rmse {va['rmse']:.4g}{_in_noise(noise, 'validation')}, e_r {va['e_r_percent']:.3g} %"
    print(line + _noise_sd(noise))
    med = doc.get("median")
    if med:
        mv = med["metrics"]["validation"]
        print(
            f"median of {', '.join(med['members'])}: validation rmse {mv['rmse']:.4g}"
            f"{_in_noise(med['metrics']['noise'], 'validation')}, e_r {mv['e_r_percent']:.3g} % -> {out / med['file']}"
        )
    cover = doc["split"].get("coverage", {}).get("warning")
    if cover:  # the validation block lies on a branch training never visited: its error is not a prediction error
        print(f"warning: {cover}", file=sys.stderr)
    _print_extras(doc)
    print(f"wrote {out / 'fit.json'}, {out / 'report.md'}" + ("" if args.no_figures else " and figures"))
    _say_leftovers(out, started)
    return 0


def _say_leftovers(out, started):
    from .._io import leftovers_note

    note = leftovers_note(out, started)
    if note:
        print(note, file=sys.stderr)


def _accelerator_note():
    """A line for a fit that would run on a GPU / TPU, else None: fitting records is a chain of sequential scans."""
    import jax

    backend = jax.default_backend()
    if backend == "cpu":
        return None
    return (
        f"note: JAX runs on '{backend}' here; fitting is a chain of sequential scans, measured 100-200x slower on an "
        "H100 than on a CPU for one record (17-22 us per scan step there; benchmarks/README.md, 'On a GPU'): "
        "JAX_PLATFORMS=cpu smafl fit ... runs faster"
    )


def _gain_prior_arg(text):
    """``--gain-prior``: a number > 0, or none."""
    import argparse

    from ..identify._gain_prior import check_gain_prior

    if text.strip().lower() == "none":
        return None
    try:
        return check_gain_prior(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def record_fit_options(args, *, progress: bool = True) -> dict:
    """The keywords `smafl fit` passes to `smafl_jax.report.fit_record` for one record, from its parsed flags (batch
    scripts such as experiments/fit_folder.py fit what the CLI fits by calling this).  `UserInputError` on a flag
    out of its range."""
    from .._errors import UserInputError

    if args.max_steps < 0:
        raise UserInputError(f"--max-steps must be >= 0, got {args.max_steps}")
    for name in ("n_sym", "n_alpha", "n_asym"):
        if getattr(args, name) < 0:
            raise UserInputError(f"--{name.replace('_', '-')} must be >= 0, got {getattr(args, name)}")
    if args.poly_order < 1:
        raise UserInputError(f"--poly-order must be >= 1, got {args.poly_order}")
    grid = dict(n_sym=args.n_sym, n_alpha=args.n_alpha, n_asym=args.n_asym, poly_order=args.poly_order)
    return dict(
        split=args.split,
        val_fraction=args.val_fraction,
        refit=not args.no_refit,
        memory=args.memory,
        early_stopping=args.early_stopping,
        median=args.median,
        slow_mode=args.slow_mode,
        **{**_model_options(args, grid), "progress": progress},
    )


def _model_options(args, grid):
    """The fit options one-record and several-record fits share."""
    return dict(
        model=args.model,
        solver=args.solver,
        max_steps=args.max_steps,
        thresholds=args.thresholds,
        tilts=args.tilts,
        orientation=args.orientation,
        thermal_start=args.thermal_start,
        sees=args.sees,
        gain_prior=args.gain_prior,
        grid=grid,
        sparse_grid=args.sparse_grid,
        hold_input=args.hold_input,
        progress=True,
    )


def _in_noise(noise, name):
    """`` (1.02x noise)`` for a metric with a noise ratio in fit.json's ``metrics.noise``, else empty."""
    r = noise.get(f"{name}_ratio")
    return f" ({r:.3g}x noise)" if r is not None else ""


def _noise_sd(noise):
    return f"; output noise SD {noise['sd']:.3g} (estimated from the data)" if noise.get("sd") else ""


def _print_extras(doc):
    """Baseline verdicts and the data-check summary of a fit.json document."""
    for sentence in (doc.get("baselines") or {}).get("verdict", []):
        print(f"baselines: {sentence}")
    dc = doc.get("data_checks") or {}
    if dc.get("n_findings"):
        counts = ", ".join(f"{n} {k}" for k, n in sorted(dc["counts"].items()))
        print(f"data checks: {dc['n_findings']} finding(s) ({counts}); see report.md (nothing was changed)")
        for f in dc.get("findings", []):
            if f["action"] == "check":  # a finding that may explain the fit's error itself: worth reading now
                print(f"data checks: {f['record']} {f['kind']}: {f['message']}")


def _run_records(args, records, grid):
    """Several records: one joint model, leave-one-record-out validation, outputs like a one-record fit."""
    from .. import prepare_out_dir
    from ..identify._metrics import ABOVE_NOISE
    from ..identify._multi_record import START_MISMATCH, fit_records, write_records_outputs

    started = time.time()
    out = prepare_out_dir(args.out or f"fit_{records[0].name}_and_{len(records) - 1}_more")
    print(
        f"fitting {args.model} jointly to {len(records)} records ({sum(len(r) for r in records)} samples, "
        f"{records[0].input_name} -> {records[0].output_name})",
        file=sys.stderr,
    )
    model, doc, details = fit_records(records, split="none" if args.split == "none" else "auto", **_model_options(args, grid))
    if args.split not in ("auto", "none"):
        print(
            f"note: --split {args.split} applies to one record; several records are validated leave-one-record-out",
            file=sys.stderr,
        )
    if args.early_stopping:
        print("note: --early-stopping applies to one record (its validation samples); not used here", file=sys.stderr)
    if args.median:
        print("note: --median applies to one record (its validation samples); not written here", file=sys.stderr)
    if args.slow_mode != "auto":
        print("note: --slow-mode applies to one record; several records are fitted with one thermal mode", file=sys.stderr)
    write_records_outputs(out, records, doc, details, figures=not args.no_figures)
    for note in doc["notes"]:
        if note.startswith((ABOVE_NOISE, START_MISMATCH)):
            print(f"warning: {note}", file=sys.stderr)
    sv = doc["solver"]
    if not sv["converged"]:
        print(f"warning: {sv['message']}", file=sys.stderr)
    tr = doc["metrics"]["train"]
    noise = doc["metrics"].get("noise") or {}
    print(
        f"joint fit on all {len(records)} records (in sample): rmse {tr['rmse']:.4g}{_in_noise(noise, 'train')}, "
        f"e_r {tr['e_r_percent']:.3g} %{_noise_sd(noise)}"
    )
    v = doc["validation"]
    if v["folds"]:
        per_record = noise.get("per_record_sd") or []
        for i, f in enumerate(v["folds"]):
            m = f["model"]
            bl = ", ".join(f"{k} {b['rmse']:.4g}" for k, b in f["baselines"].items())
            # each held-out record against its own noise SD (one rig differs: NiTi electric 0.06-0.09, water 0.014-0.017)
            sd = per_record[i] if i < len(per_record) and per_record[i] else noise.get("sd")
            ratio = f" ({m['rmse'] / sd:.3g}x its noise)" if m and sd else ""
            head = f"rmse {m['rmse']:.4g}{ratio}, e_r {m['e_r_percent']:.3g} %" if m else "non-finite output"
            print(f"  held out {f['record']}: {head} (baselines rmse: {bl})")
        mm = v["mean"]["model"]
        if mm:
            print(
                f"leave-one-record-out mean: rmse {mm['rmse']:.4g}{_in_noise(noise, 'validation')}, "
                f"e_r {mm['e_r_percent']:.3g} % ({mm['n_folds']} of {len(v['folds'])} folds)"
            )
    _print_extras(doc)
    print(f"wrote {out / 'fit.json'}, {out / 'report.md'}" + ("" if args.no_figures else " and figures"))
    _say_leftovers(out, started)
    return 0
