"""``smafl simulate PARAMS.json INPUT.csv --out OUT.csv [--resample DT|auto]``: run a saved model on an input record.

Warns (stderr, and ``input_range_check`` / ``effective_input_range_check`` in the ``--metrics`` JSON)
when the input, or a cascade's hysteresis input, leaves the range the model was fitted on
(``data.input_range`` / ``data.effective_input_range`` of a fit.json): when, for how long and by how much.
A model file without that range is run with a note that the range could not be checked.

``--calibrate START:END`` re-anchors the model on that stretch of the new record (`smafl_jax.recalibrate`:
input gain and offset, output offset, fitted on the segment only; ``--calibrate-fit`` picks which) and writes
the re-anchored output; the metrics then cover only the samples after the segment (``scored_from_s``), for the
raw and the re-anchored model side by side, and the range check applies to the re-anchored input.
"""

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
    p.add_argument("--metrics", default=None, help="also write those metrics (and the input-range check) to this JSON file")
    p.add_argument(
        "--resample",
        default=None,
        metavar="DT|auto",
        help="put irregular time stamps on a uniform DT-second grid by linear interpolation ('auto' = median step); "
        "the output CSV is on that grid. Without it irregular sampling is an error",
    )
    p.add_argument(
        "--initial-state",
        choices=("fit", "steady", "cold", "estimate"),
        default="fit",
        help="start state on this record: fit (the fitted record's thermal start and operator memory, default), "
        "steady (at rest with the first input), cold (ambient), or estimate (the start that best matches the "
        "measured column over the first 20 %% of the record / 5 time constants)",
    )
    p.add_argument(
        "--method",
        choices=("auto", "scan", "assoc", "chunked", "segmented"),
        default=None,
        help="evaluation form of the thermal lag and operator bank (default: the model's own, normally scan); "
        "assoc/chunked/segmented are exact parallel-in-time forms, auto picks by backend and record length",
    )
    p.add_argument(
        "--calibrate",
        default=None,
        metavar="START:END",
        help="re-anchor the model on this segment of the record (seconds on its time_s axis, e.g. 0:30; "
        "half-open) before simulating: input gain and offset and output offset fitted by least squares on the "
        "segment only (needs the measured column); metrics then count only the samples after the segment",
    )
    p.add_argument(
        "--calibrate-fit",
        default=None,
        metavar="NAMES",
        help="comma-separated parameters --calibrate fits: input_gain, input_offset, output_offset (default: all three)",
    )
    p.set_defaults(func=run)
    return p


def parse_calibrate(text: str) -> tuple[float | None, float]:
    """``"START:END"`` (seconds; START may be empty = the record's start) -> ``(start, end)``."""
    parts = text.split(":")
    if len(parts) != 2 or not parts[1].strip():
        raise UserInputError(f"--calibrate {text!r}: expected START:END in seconds, e.g. 0:30")
    try:
        start = float(parts[0]) if parts[0].strip() else None
        end = float(parts[1])
    except ValueError:
        raise UserInputError(f"--calibrate {text!r}: START and END must be numbers of seconds, e.g. 0:30") from None
    return start, end


def run(args):
    from .. import load_model_file, load_record, simulate
    from .._data import parse_resample
    from .._io import atomic_write_csv, check_writable_file

    check_writable_file(args.out)  # before the simulation: a bad path fails at once
    segment = parse_calibrate(args.calibrate) if args.calibrate else None
    if args.calibrate_fit is not None and segment is None:
        raise UserInputError("--calibrate-fit needs --calibrate START:END")
    calibrate_fit = None
    if segment is not None:
        from .._recalibrate import _check_fit_names

        names = [n.strip() for n in (args.calibrate_fit or "input_gain,input_offset,output_offset").split(",") if n.strip()]
        calibrate_fit = _check_fit_names(names)
    if args.metrics:
        check_writable_file(args.metrics, "metrics file")
    model, doc = load_model_file(args.params)
    if args.method is not None:
        from .._operators import model_with_method

        try:
            model = model_with_method(model, args.method)
        except ValueError as exc:
            raise UserInputError(f"{args.params}: --method {args.method}: {exc}") from None
    data_info = doc.get("data", {}) if isinstance(doc.get("data"), dict) else {}
    in_col = args.input or data_info.get("input_column")
    rec = load_record(args.input_csv, input=in_col, require_output=False, min_samples=2, resample=parse_resample(args.resample))
    for note in rec.processing:
        print(f"note: loading {rec.name}: {note}", file=sys.stderr)
    fit_dt = data_info.get("sample_time_s")
    if fit_dt and not np.isclose(fit_dt, rec.dt, rtol=0.02):
        print(
            f"note: the model was fitted at dt={fit_dt:g} s and this record has dt={rec.dt:g} s; "
            "the thermal part accounts for it, a rate-independent EUPI does not care",
            file=sys.stderr,
        )
    if args.initial_state != "fit":
        from .._initial_state import with_initial_state

        meas = args.measured or data_info.get("output_column")
        y_meas = np.asarray(rec.extra[meas], dtype=np.float64) if meas in rec.extra else None
        model, start = with_initial_state(model, args.initial_state, rec.u, y_meas, rec.dt)
        detail = f": thermal {start['thermal']}, operator memory {start['memory']}" if "thermal" in start else ""
        print(f"note: initial state {args.initial_state}{detail}", file=sys.stderr)
    measured = args.measured or data_info.get("output_column")
    if args.measured and measured not in rec.extra:
        raise UserInputError(f"{args.input_csv}: no column {measured!r} to score against; columns: {sorted(rec.extra)}")
    calibration = None
    raw_model = model
    if segment is not None:
        from .._recalibrate import recalibrate

        if measured not in rec.extra:
            raise UserInputError(
                f"--calibrate needs the measured output column in {args.input_csv} (see --measured); columns: {sorted(rec.extra)}"
            )
        model, calibration = recalibrate(
            model,
            rec.u,
            np.asarray(rec.extra[measured], dtype=np.float64),
            rec.dt,
            segment,
            fit=calibrate_fit,
            t0=float(rec.time[0]),
        )
        if args.metrics and calibration["scored_from_sample"] >= len(rec):
            raise UserInputError(
                f"--calibrate {args.calibrate}: the segment reaches the end of the record, so nothing after it is left to score"
            )
        seg = calibration["segment"]
        print(
            f"calibration on {seg['start_s']:.6g}-{seg['end_s']:.6g} s ({seg['n_samples']} samples, fitted: "
            f"{', '.join(calibration['fitted'])}): input_gain {calibration['input_gain']:.6g}, input_offset "
            f"{calibration['input_offset']:.6g}, output_offset {calibration['output_offset']:.6g}; segment RMSE "
            f"{calibration['segment_rmse_before']:.4g} -> {calibration['segment_rmse_after']:.4g}"
        )
        if calibration["at_bound"]:
            print(
                f"warning: calibration: {', '.join(calibration['at_bound'])} ended at its bound {calibration['bounds']}: "
                "the segment does not determine it; use a longer segment or --calibrate-fit output_offset",
                file=sys.stderr,
            )
    from .._range import model_range_checks

    if calibration is None:
        checks = model_range_checks(model, data_info, rec.u, rec.dt, rec.input_name)
    else:  # the wrapped model sees the re-anchored input: that is the one to hold against the fitted range
        u_seen = np.asarray(model.model_input(np.asarray(rec.u, dtype=np.float64)))
        checks = model_range_checks(model.model, data_info, u_seen, rec.dt, f"{rec.input_name} (re-anchored)")
    range_check, effective_check = checks[0], (checks[1] if len(checks) > 1 else None)
    for chk in checks:
        if chk.get("warning"):
            print(f"warning: {chk['warning']}", file=sys.stderr)
        elif chk.get("note"):
            print(f"note: {chk['note']}", file=sys.stderr)
    y = np.asarray(simulate(model, rec.u, rec.dt))
    if not np.all(np.isfinite(y)):
        raise UserInputError(f"{args.params}: the model produced non-finite output on {args.input_csv}")
    out_name = args.output_name or f"{data_info.get('output_column') or 'output'}_model"
    if out_name in ("time_s", rec.input_name):
        raise UserInputError(f"--output-name {out_name!r} clashes with an input column")
    cols = {"time_s": rec.time, rec.input_name: rec.u, out_name: y}
    scored = None
    y_raw = None
    if calibration is not None:
        y_raw = np.asarray(simulate(raw_model, rec.u, rec.dt))
        raw_name = f"{out_name}_uncalibrated"
        if raw_name in (rec.input_name, measured):
            raise UserInputError(f"--output-name {out_name!r}: the uncalibrated column {raw_name!r} clashes with a data column")
        cols[raw_name] = y_raw
    if measured in rec.extra and measured != out_name:
        from .._metrics import metrics

        ym = np.asarray(rec.extra[measured], dtype=np.float64)
        if calibration is None:
            scored = {"measured_column": measured, **metrics(ym, y)}
        elif calibration["scored_from_sample"] < len(rec):
            from .._recalibrate import after_segment_metrics

            after = after_segment_metrics(ym, y_raw, y, calibration["scored_from_sample"])
            scored = {
                "measured_column": measured,
                "scored_from_s": calibration["scored_from_s"],
                "scored_from_sample": calibration["scored_from_sample"],
                **after["recalibrated"],
                "raw_after_segment": after["raw"],
                "recalibrated_after_segment": after["recalibrated"],
            }
        cols[measured] = ym
    if args.metrics and scored is None:  # checked before anything is written
        raise UserInputError("--metrics needs a measured output column in the CSV (see --measured)")
    out = Path(args.out)
    if out.exists():
        print(f"note: replacing existing {out}", file=sys.stderr)
    atomic_write_csv(out, cols)
    print(f"wrote {out} ({len(rec)} samples, column '{out_name}')")
    if scored is not None and calibration is not None:
        raw, cal = scored["raw_after_segment"], scored["recalibrated_after_segment"]
        print(
            f"against measured '{measured}' after the segment (from {scored['scored_from_s']:.6g} s, {cal['n_samples']} samples): "
            f"raw RMSE {raw['rmse']:.4g}, e_r {_pct(raw['e_r_percent'])}; re-anchored RMSE {cal['rmse']:.4g}, "
            f"e_r {_pct(cal['e_r_percent'])} (eq. 3)"
        )
    elif scored is not None:
        print(
            f"against measured '{measured}': RMSE {scored['rmse']:.4g}, max |error| {scored['max_abs_error']:.4g}, "
            + (
                f"e_r {scored['e_r_percent']:.2f} % (eq. 3)"
                if np.isfinite(scored["e_r_percent"])
                else "e_r undefined (eq. 3: the measured output is constant)"
            )
        )
    if args.metrics:
        from .._io import atomic_write_json

        if scored is None:
            raise UserInputError("--metrics needs a measured output column in the CSV (see --measured)")
        atomic_write_json(
            args.metrics,
            {
                "model": str(args.params),
                "data": str(args.input_csv),
                "n_samples": len(rec),
                **scored,  # with --calibrate its n_samples counts the scored samples after the segment
                **({"n_record_samples": len(rec), "calibration": calibration} if calibration is not None else {}),
                "input_range_check": range_check,
                "effective_input_range_check": effective_check,
                "processing": list(rec.processing),
            },
        )
    return 0


def _pct(x: float) -> str:
    return f"{x:.2f} %" if np.isfinite(x) else "undefined (constant measured output)"


def input_range_check(u, fitted_range, column: str = "input", dt: float | None = None) -> dict:
    """How far and how often ``u`` leaves ``fitted_range`` (see `smafl_jax._range.range_check`)."""
    from .._range import range_check

    return range_check(u, fitted_range, column, dt=dt)
