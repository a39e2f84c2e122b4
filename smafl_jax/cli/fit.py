"""``smafl fit DATA.csv [--model eupi|cascade|joule] --out DIR``: identify a model from one record.

Writes ``fit.json`` (model, train/validation metrics, data hash, settings,
versions), ``report.md`` and figures into DIR.
"""

from __future__ import annotations

import sys
from pathlib import Path


def add_parser(sub):
    from .._fit import SOLVERS
    from .._report_fit import MODELS
    from .._split import SPLITS

    p = sub.add_parser("fit", help="fit a model to a record: fit.json, report.md and figures")
    p.add_argument("data", help="record CSV (time_s, input and output columns; optional branch column)")
    p.add_argument("--input", default=None, help="input column (default: sidecar, else a common name such as voltage_V)")
    p.add_argument("--output", default=None, help="output column (default: sidecar, else e.g. displacement_mm)")
    p.add_argument(
        "--model",
        choices=MODELS,
        default="eupi",
        help="eupi (paper eq. 2), cascade (thermal + EUPI), joule (eq. 7 lag); default eupi",
    )
    p.add_argument("--out", default=None, help="output folder (default: fit_<data stem>)")
    p.add_argument(
        "--split",
        choices=SPLITS,
        default="auto",
        help="validation split: branch (every 3rd branch), time (last part), none; auto = branch if a 'branch' column exists",
    )
    p.add_argument("--val-fraction", type=float, default=0.3, help="held-out fraction for the time split (default 0.3)")
    p.add_argument("--solver", choices=SOLVERS, default="lm", help="joint refinement solver (default lm)")
    p.add_argument("--max-steps", type=int, default=300, help="refinement steps (0 = initialiser only)")
    p.add_argument("--thresholds", action="store_true", help="also train the play thresholds")
    p.add_argument("--tilts", action="store_true", help="also train the unparallel tilts")
    p.add_argument("--n-sym", type=int, default=8, help="symmetric play operators (default 8)")
    p.add_argument("--n-alpha", type=int, default=4, help="tilts of unparallel operators (default 4)")
    p.add_argument("--n-asym", type=int, default=4, help="thresholds per tilt (default 4)")
    p.add_argument("--poly-order", type=int, default=3, help="polynomial order (default 3, as in the paper)")
    p.add_argument("--no-figures", action="store_true", help="skip the figures")
    p.set_defaults(func=run)
    return p


def run(args):
    from .. import load_record, prepare_out_dir
    from .._errors import UserInputError
    from .._report_fit import fit_record, write_fit_outputs

    if args.max_steps < 0:
        raise UserInputError(f"--max-steps must be >= 0, got {args.max_steps}")
    for name in ("n_sym", "n_alpha", "n_asym"):
        if getattr(args, name) < 0:
            raise UserInputError(f"--{name.replace('_', '-')} must be >= 0, got {getattr(args, name)}")
    if args.poly_order < 1:
        raise UserInputError(f"--poly-order must be >= 1, got {args.poly_order}")
    rec = load_record(args.data, input=args.input, output=args.output)
    out = prepare_out_dir(args.out or f"fit_{Path(args.data).stem}")
    grid = dict(n_sym=args.n_sym, n_alpha=args.n_alpha, n_asym=args.n_asym, poly_order=args.poly_order)
    print(f"fitting {args.model} to {args.data} ({len(rec)} samples, {rec.input_name} -> {rec.output_name})", file=sys.stderr)
    model, doc, masks = fit_record(
        rec,
        model=args.model,
        split=args.split,
        val_fraction=args.val_fraction,
        solver=args.solver,
        max_steps=args.max_steps,
        thresholds=args.thresholds,
        tilts=args.tilts,
        grid=grid,
        progress=True,
    )
    write_fit_outputs(out, rec, doc, masks, figures=not args.no_figures)
    sv = doc["solver"]
    if not sv["converged"]:
        print(f"warning: {sv['message']}", file=sys.stderr)
    tr, va = doc["metrics"]["train"], doc["metrics"]["validation"]
    line = f"train rmse {tr['rmse']:.4g}, e_r {tr['e_r_percent']:.3g} %"
    if va:
        line += f"; validation rmse {va['rmse']:.4g}, e_r {va['e_r_percent']:.3g} %"
    print(line)
    print(f"wrote {out / 'fit.json'}, {out / 'report.md'}" + ("" if args.no_figures else " and figures"))
    return 0
