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
    out = Path(args.out)
    if out.exists():
        print(f"note: replacing existing {out}", file=sys.stderr)
    atomic_write_csv(out, {"time_s": rec.time, rec.input_name: rec.u, out_name: y})
    print(f"wrote {out} ({len(rec)} samples, column '{out_name}')")
    return 0
