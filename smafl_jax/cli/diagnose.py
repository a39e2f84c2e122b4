"""``smafl diagnose DATA.csv --out DIR``: residual diagnosis and effect attribution (issue 6)."""

from __future__ import annotations

import sys


def add_parser(sub):
    p = sub.add_parser("diagnose", help="fit the base model, study its residuals, attribute and fit missing physical effects")
    p.add_argument("data", help="CSV record (time_s, input, output, optional extra columns such as branch, load, ambient)")
    p.add_argument("--input", default=None, help="input column (default: sidecar, then a common name)")
    p.add_argument("--output", default=None, help="output column (default: sidecar, then a common name)")
    p.add_argument(
        "--out",
        required=True,
        help="output folder (diagnosis.json, extended_fit.json, base_fit.json, their *_train.json split fits, report.md, plots)",
    )
    p.add_argument(
        "--effects", nargs="+", default=None, help="restrict the candidate effects (catalogue names); default: all applicable"
    )
    p.add_argument("--max-candidates", type=int, default=3, help="fit at most this many plausible effects (default 3)")
    p.add_argument(
        "--min-gain", type=float, default=0.05, help="relative held-out RMSE reduction an effect must bring (default 0.05)"
    )
    p.add_argument(
        "--no-refit",
        action="store_true",
        help="write the split fits as extended_fit.json / base_fit.json instead of refitting "
        "the selected structure on the whole record",
    )
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.set_defaults(func=run)
    return p


def run(args):
    from .._data import load_record
    from .._errors import UserInputError
    from .._io import prepare_out_dir
    from .._report import write_diagnosis

    if args.max_candidates < 1:
        raise UserInputError(f"--max-candidates must be >= 1, got {args.max_candidates}")
    if not 0.0 <= args.min_gain < 1.0:
        raise UserInputError(f"--min-gain must be in [0, 1), got {args.min_gain}")
    rec = load_record(args.data, input=args.input, output=args.output)
    out = prepare_out_dir(args.out)
    from .._diagnose import diagnose

    res, base, ext, split = diagnose(
        rec,
        effects=args.effects,
        max_candidates=args.max_candidates,
        min_gain=args.min_gain,
        refit=not args.no_refit,
        verbose=not args.quiet,
    )
    write_diagnosis(out, rec, res, base, ext, split)
    warning = res["split"].get("coverage", {}).get("warning")
    if warning:
        print(f"warning: {warning}", file=sys.stderr)
    sel = ", ".join(res["selected"]) or "none"
    print(
        f"selected: {sel}; held-out RMSE {res['base']['heldout_rmse']:.4g} -> {res['extended']['heldout_rmse']:.4g} "
        f"(e_r {res['base']['heldout']['e_r_percent']:.2f} % -> {res['extended']['heldout']['e_r_percent']:.2f} %); wrote {out}"
    )
    return 0
