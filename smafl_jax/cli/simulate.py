"""``smafl simulate PARAMS.json INPUT.csv --out OUT.csv [--resample DT|auto]``: run a saved model on an input record.

Warns (stderr, and ``input_range_check`` / ``effective_input_range_check`` in the ``--metrics`` JSON)
when the input, or a cascade's hysteresis input, leaves the range the model was fitted on
(``data.input_range`` / ``data.effective_input_range`` of a fit.json) by more than 1 % of the fitted span
(`models._range.RANGE_TOL`; smaller exits are counted in the JSON only): when, for how long and by how much.
A model file without that range is run with a note that the range could not be checked.  It also warns
(``branch_check``) when the hysteresis input walks a branch its training never visited across 10 % or more of the
trained span, even inside the range (``data.trained_branches``; a wire heated but never cooled in training).

``--calibrate START:END`` re-anchors the model on that stretch of the new record (`smafl_jax.recalibrate`:
input gain and offset, output offset, fitted on the segment only; ``--calibrate-fit`` picks which) and writes
the re-anchored output; the metrics then cover only the samples after the segment (``scored_from_s``), for the
raw and the re-anchored model side by side, and the range check applies to the re-anchored input.  It warns when
the calibration ends at a bound, when its refinement did not converge, when it fits its own segment no better than the
raw model, and when the re-anchored output scores worse than the raw one after the segment (the raw output is the
``_uncalibrated`` column).
"""

from __future__ import annotations

import numpy as np

from .check import TIME_HELP
from .control import OPTION_NAMES, workflow_lines_on_stderr


def add_parser(sub):
    p = sub.add_parser("simulate", help="run a saved model (model file or fit.json) on an input record")
    p.add_argument("params", help="model JSON: a saved model file or the fit.json written by `smafl fit`")
    p.add_argument("input_csv", help="CSV with a time column (time_s, or see --time) and the input column")
    p.add_argument("--out", required=True, help="output CSV (time_s, input, simulated output)")
    p.add_argument("--input", default=None, help="input column (default: the fit's input column, else a common name)")
    p.add_argument("--time", default=None, metavar="COL", help=TIME_HELP)
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
    p.add_argument(
        "--measured-sign",
        type=int,
        choices=(1, -1),
        default=1,
        help="-1: the measured column reads the other way (a reversed sensor): score and calibrate against its "
        "negative (the output CSV keeps it as read); simulate warns when the column runs against the model",
    )
    p.set_defaults(func=run)
    return p


def run(args):
    from ..workflows.simulate import simulate_record

    with workflow_lines_on_stderr():
        res = simulate_record(
            args.params,
            args.input_csv,
            out=args.out,
            metrics_file=args.metrics,
            input=args.input,
            time=args.time,
            output_name=args.output_name,
            measured=args.measured,
            resample=args.resample,
            initial_state=args.initial_state,
            method=args.method,
            calibrate=args.calibrate,
            calibrate_fit=args.calibrate_fit,
            measured_sign=args.measured_sign,
            option_names=OPTION_NAMES,
        )
    cal, scored, measured = res.calibration, res.scores, res.measured
    if cal is not None:
        seg = cal["segment"]
        print(
            f"calibration on {seg['start_s']:.6g}-{seg['end_s']:.6g} s ({seg['n_samples']} samples, fitted: "
            f"{', '.join(cal['fitted'])}): input_gain {cal['input_gain']:.6g}, input_offset "
            f"{cal['input_offset']:.6g}, output_offset {cal['output_offset']:.6g}; segment RMSE "
            f"{cal['segment_rmse_before']:.4g} -> {cal['segment_rmse_after']:.4g}"
        )
    print(f"wrote {res.out} ({len(res.record)} samples, column '{res.output_name}')")
    if scored is not None and cal is not None:
        raw, after = scored["raw_after_segment"], scored["recalibrated_after_segment"]
        print(
            f"against measured '{measured}' after the segment (from {scored['scored_from_s']:.6g} s, {after['n_samples']} samples"
            f"{_left_out(scored)}): "
            f"raw RMSE {raw['rmse']:.4g}, e_r {_pct(raw['e_r_percent'])}; re-anchored RMSE {after['rmse']:.4g}, "
            f"e_r {_pct(after['e_r_percent'])} (eq. 3){_in_noise(scored)}"
        )
    elif scored is not None:
        print(
            f"against measured '{measured}'{_left_out(scored, own=True)}: RMSE {scored['rmse']:.4g}{_in_noise(scored)}, max |error| "
            f"{scored['max_abs_error']:.4g}, "
            + (
                f"e_r {scored['e_r_percent']:.2f} % (eq. 3)"
                if np.isfinite(scored["e_r_percent"])
                else "e_r undefined (eq. 3: the measured output is constant)"
            )
        )
    return 0


def _in_noise(scored: dict) -> str:
    """`` (3.2x the output noise)`` from the scores' noise ratio (`smafl_jax.noise_floor`), else empty."""
    r = (scored.get("noise") or {}).get("scored_ratio")
    return f" ({r:.3g}x the measured output's noise SD)" if r is not None else ""


def _left_out(scored: dict, own: bool = False) -> str:
    """How many blank / NaN measured samples the scores left out (empty when none); ``own``: in brackets."""
    n = scored.get("n_left_out")
    if not n:
        return ""
    text = f"{n} blank/NaN measured sample(s) left out of the score"
    return f" ({scored['n_samples']} samples, {text})" if own else f"; {text}"


def _pct(x: float) -> str:
    return f"{x:.2f} %" if np.isfinite(x) else "undefined (constant measured output)"


def input_range_check(u, fitted_range, column: str = "input", dt: float | None = None, t0: float = 0.0) -> dict:
    """How far and how often ``u`` leaves ``fitted_range`` (see `smafl_jax.models._range.range_check`; ``t0``: the
    time of the first sample)."""
    from ..models._range import range_check

    return range_check(u, fitted_range, column, dt=dt, t0=t0)
