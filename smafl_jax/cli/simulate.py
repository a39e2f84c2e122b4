"""``smafl simulate PARAMS.json INPUT.csv --out OUT.csv``: run a saved model on an input record."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from .._errors import UserInputError


def add_parser(sub):
    p = sub.add_parser("simulate", help="run a saved model (model file or fit.json) on an input record")
    p.add_argument("params", help="model JSON: a saved model file or the fit.json written by `smafl fit`")
    p.add_argument("input_csv", help="CSV with a time_s column and the input column")
    p.add_argument("--out", required=True, help="output CSV (time_s, input, simulated output)")
    p.add_argument("--input", default=None, help="input column (default: the fit's input column, else a common name)")
    p.add_argument("--output-name", default=None, help="name of the simulated column (default: <fit output>_model)")
    p.add_argument(
        "--measured",
        default=None,
        help="measured output column to score against (default: the fit's output column when the CSV has it); "
        "prints RMSE and e_r and copies the column into the output CSV",
    )
    p.add_argument("--metrics", default=None, help="also write those metrics to this JSON file")
    p.set_defaults(func=run)
    return p


def run(args):
    from .. import load_model_file, load_record, simulate
    from .._io import atomic_write_csv

    model, doc = load_model_file(args.params)
    data_info = doc.get("data", {}) if isinstance(doc.get("data"), dict) else {}
    in_col = args.input or data_info.get("input_column")
    rec = load_record(args.input_csv, input=in_col, require_output=False, min_samples=2)
    fit_dt = data_info.get("sample_time_s")
    if fit_dt and not np.isclose(fit_dt, rec.dt, rtol=0.02):
        print(
            f"note: the model was fitted at dt={fit_dt:g} s and this record has dt={rec.dt:g} s; "
            "the thermal part accounts for it, a rate-independent EUPI does not care",
            file=sys.stderr,
        )
    y = np.asarray(simulate(model, rec.u, rec.dt))
    if not np.all(np.isfinite(y)):
        raise UserInputError(f"{args.params}: the model produced non-finite output on {args.input_csv}")
    out_name = args.output_name or f"{data_info.get('output_column') or 'output'}_model"
    if out_name in ("time_s", rec.input_name):
        raise UserInputError(f"--output-name {out_name!r} clashes with an input column")
    measured = args.measured or data_info.get("output_column")
    if args.measured and measured not in rec.extra:
        raise UserInputError(f"{args.input_csv}: no column {measured!r} to score against; columns: {sorted(rec.extra)}")
    cols = {"time_s": rec.time, rec.input_name: rec.u, out_name: y}
    scored = None
    if measured in rec.extra and measured != out_name:
        from .._metrics import metrics

        ym = np.asarray(rec.extra[measured], dtype=np.float64)
        scored = {"measured_column": measured, **metrics(ym, y)}
        cols[measured] = ym
    out = Path(args.out)
    if out.exists():
        print(f"note: replacing existing {out}", file=sys.stderr)
    atomic_write_csv(out, cols)
    print(f"wrote {out} ({len(rec)} samples, column '{out_name}')")
    if scored is not None:
        print(
            f"against measured '{measured}': RMSE {scored['rmse']:.4g}, max |error| {scored['max_abs_error']:.4g}, "
            f"e_r {scored['e_r_percent']:.2f} % (eq. 3)"
        )
    if args.metrics:
        from .._io import atomic_write_json

        if scored is None:
            raise UserInputError("--metrics needs a measured output column in the CSV (see --measured)")
        atomic_write_json(args.metrics, {"model": str(args.params), "data": str(args.input_csv), "n_samples": len(rec), **scored})
    return 0
