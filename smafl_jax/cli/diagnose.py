"""``smafl diagnose DATA.csv --out DIR``: residual diagnosis and effect attribution (issue 6)."""

from __future__ import annotations

import sys

from .check import TIME_HELP, add_resample_argument, add_window_argument, apply_window


def add_parser(sub):
    p = sub.add_parser("diagnose", help="fit the base model, study its residuals, attribute and fit missing physical effects")
    p.add_argument(
        "data",
        nargs="+",
        help="CSV record (time_s, input, output, optional extra columns such as branch, load, ambient); several files, a "
        "folder (its *.csv) or a glob: each record diagnosed on its own (OUT/<record>/), an effect named for the set when "
        "selected on more than half of them (OUT/diagnosis.json, OUT/report.md)",
    )
    p.add_argument("--input", default=None, help="input column (default: sidecar, then a common name)")
    p.add_argument("--output", default=None, help="output column (default: sidecar, then a common name)")
    p.add_argument("--time", default=None, metavar="COL", help=TIME_HELP)
    add_resample_argument(p)
    add_window_argument(p)
    p.add_argument(
        "--out",
        required=True,
        help="output folder (diagnosis.json, extended_fit.json, base_fit.json, their *_train.json split fits, report.md, plots)",
    )
    p.add_argument(
        "--effects", nargs="+", default=None, help="restrict the candidate effects (catalogue names); default: all applicable"
    )
    p.add_argument(
        "--max-candidates",
        type=int,
        default=None,
        help="fit at most this many plausible effects, best score-test evidence first (default: every applicable effect)",
    )
    p.add_argument(
        "--min-gain", type=float, default=0.05, help="relative held-out RMSE reduction an effect must bring (default 0.05)"
    )
    p.add_argument(
        "--rule",
        choices=("calibrated", "legacy"),
        default="calibrated",
        help="selection rule: calibrated (folds + parametric-bootstrap null records, default) or legacy (one split + BIC)",
    )
    p.add_argument("--fpr", type=float, default=0.01, help="false-positive rate of the calibrated rule (default 0.01)")
    p.add_argument(
        "--n-null",
        type=int,
        default=10,
        help="null records per tested effect (calibrated rule; default 10, kept small for speed)",
    )
    p.add_argument("--n-folds", type=int, default=3, help="contiguous time blocks for the fold test (default 3)")
    p.add_argument("--seed", type=int, default=0, help="seed of the null records (default 0)")
    p.add_argument(
        "--no-refit",
        action="store_true",
        help="write the split fits as extended_fit.json / base_fit.json instead of refitting "
        "the selected structure on the whole record",
    )
    p.add_argument(
        "--base-start",
        choices=("screened", "fixed"),
        default="screened",
        help="base model start: 'screened' (default: output orientation, hysteresis input and thermal start chosen on the "
        "training samples, as smafl fit does) or 'fixed' (rising output, at rest with the first input: earlier versions)",
    )
    p.add_argument(
        "--no-refine",
        action="store_true",
        help="keep the base at its variable-projection fit with the rule operator memory and fit only the 3 effects with "
        "the best score-test evidence (faster; earlier versions). Default: base and every candidate refined jointly "
        "with thresholds, tilts and a fitted operator memory",
    )
    p.add_argument(
        "--naming",
        choices=("whole", "split"),
        default="whole",
        help="which effect is named once the calibrated gates accept one: 'whole' (default: the largest RMSE gain with "
        "every candidate refitted on the whole record; none if below --min-gain) or 'split' (the gates' best held-out "
        "candidate: earlier versions)",
    )
    p.add_argument(
        "--no-unexplained",
        action="store_true",
        help="skip the generic residual regression on the correlates (the 'unexplained' answer; never changes the selection)",
    )
    p.add_argument(
        "--no-reference",
        action="store_true",
        help="do not check an accepted effect against smafl fit's default model on the same split (default: where that "
        "model holds out at the noise floor, the acceptance is withdrawn; diagnosis.json base.reference_fit)",
    )
    p.add_argument(
        "--split",
        choices=("time", "interleaved", "auto"),
        default="auto",
        help="held-out samples of a record without a branch column: 'auto' (default: the last 30 %% unless the first "
        "70 %% covers less than 90 %% of its input levels and directions, then interleaved), 'time' (the last 30 %%) "
        "or 'interleaved' (every third of ten blocks but the first; the fold test interleaved too)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.set_defaults(func=run)
    return p


def run(args):
    from .._errors import UserInputError
    from .._io import prepare_out_dir
    from ..report._report import write_diagnosis

    if args.max_candidates is not None and args.max_candidates < 1:
        raise UserInputError(f"--max-candidates must be >= 1, got {args.max_candidates}")
    if not 0.0 <= args.min_gain < 1.0:
        raise UserInputError(f"--min-gain must be in [0, 1), got {args.min_gain}")
    if not 0.0 < args.fpr < 0.5:
        raise UserInputError(f"--fpr must be in (0, 0.5), got {args.fpr}")
    if args.n_null < 2:
        raise UserInputError(f"--n-null must be >= 2, got {args.n_null}")
    if args.n_folds < 2:
        raise UserInputError(f"--n-folds must be >= 2, got {args.n_folds}")
    from ..data import load_records
    from ..data._data import parse_resample
    from ..diagnosis._diagnose import check_record, diagnose

    loaded = load_records(args.data, input=args.input, output=args.output, time=args.time, resample=parse_resample(args.resample))
    records = apply_window(loaded, args.window)
    for rec in records:
        check_record(rec)  # before the output folder is created
    out = prepare_out_dir(args.out)
    settings = dict(
        effects=args.effects,
        max_candidates=args.max_candidates,
        min_gain=args.min_gain,
        refit=not args.no_refit,
        verbose=not args.quiet,
        rule=args.rule,
        fpr=args.fpr,
        n_null=args.n_null,
        n_folds=args.n_folds,
        seed=args.seed,
        screen=args.base_start == "screened",
        refine=not args.no_refine,
        unexplained=not args.no_unexplained,
        naming=args.naming,
        reference=not args.no_reference,
        split=args.split,
    )
    if len(records) > 1:
        return _several(records, out, settings)
    rec = records[0]
    diag = diagnose(rec, **settings)
    write_diagnosis(out, rec, diag)
    for key in ("coverage", "state_coverage"):
        warning = (diag.report["split"].get(key) or {}).get("warning")
        if warning:
            print(f"warning: {warning}", file=sys.stderr)
    for w in diag.warnings:
        print(f"warning: {w}", file=sys.stderr)
    sel = ", ".join(diag.selected) or "none"
    if diag.ambiguous:
        sel += f" (ambiguous with {', '.join(n for n in diag.ambiguous if n not in diag.selected)})"
    if diag.unspecific:
        sel += f" (unrelated effects explain the residual alike: {', '.join(diag.unspecific)})"
    noise = diag.report.get("noise") or {}
    in_noise = (
        f", {noise['base_heldout_ratio']:.3g}x -> {noise['extended_heldout_ratio']:.3g}x the output noise"
        if noise.get("base_heldout_ratio") is not None and noise.get("extended_heldout_ratio") is not None
        else ""
    )
    print(
        f"selected: {sel}; held-out RMSE {diag.heldout_rmse_before:.4g} -> {diag.heldout_rmse_after:.4g} "
        f"(e_r {diag.heldout_e_r_before:.2f} % -> {diag.heldout_e_r_after:.2f} %{in_noise}); wrote {out}"
    )
    if diag.unexplained:
        print(f"unexplained: {diag.unexplained['verdict']}")
    return 0


def _several(records, out, settings):
    """Each record diagnosed on its own, then the effects they agree on (`smafl_jax.diagnose_records`)."""
    from ..diagnosis._several import diagnose_records

    res = diagnose_records(records, out, **settings)
    rep = res.report
    for row in rep["records"]:
        for w in row["warnings"]:
            print(f"warning: {row['file']}: {w}", file=sys.stderr)
        ratio = (
            f", {row['base_heldout_over_noise']:.3g}x -> {row['extended_heldout_over_noise']:.3g}x the noise"
            if row["base_heldout_over_noise"] is not None and row["extended_heldout_over_noise"] is not None
            else ""
        )
        print(
            f"{row['file']}: selected {', '.join(row['selected']) or 'none'}; held-out RMSE {row['heldout_rmse_before']:.4g} "
            f"-> {row['heldout_rmse_after']:.4g}{ratio}"
        )
    some = f"; seen on some records only: {', '.join(rep['some_records'])}" if rep["some_records"] else ""
    print(
        f"named for the {rep['n_records']} records (selected on at least {rep['needed']}): "
        f"{', '.join(rep['consistent']) or 'none'}{some}; wrote {out}"
    )
    return 0
