"""Running a saved model on a record as one library call (the workflow behind ``smafl simulate``).

`simulate_record` loads the model (a model file, a fit.json or a model object)
and the record (a CSV path, resampled on request, or a `Record`), sets the start
state, optionally re-anchors the model on a calibration segment of the record
(`smafl_jax.recalibrate`), checks the input (or the re-anchored input) against
the range the model was fitted on, simulates, scores against the measured
column when there is one (after the segment, raw and re-anchored, with a
calibration) and writes, atomically, the output CSV and the metrics JSON.
Every setting and output path is checked before anything is written.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from .._errors import UserInputError
from .control import option_namer

if TYPE_CHECKING:
    from ..data._data import Record

PathLike = str | os.PathLike

__all__ = ["SimulationResult", "simulate_record", "parse_segment", "INITIAL_STATES", "METHODS"]

LOGGER = logging.getLogger(__name__)

INITIAL_STATES = ("fit", "steady", "cold", "estimate")
METHODS = ("auto", "scan", "assoc", "chunked", "segmented")
CALIBRATION_DEFAULT = ("input_gain", "input_offset", "output_offset")


class SimulationResult(NamedTuple):
    """What `simulate_record` produced.

    ``y``: the simulated output (re-anchored with a calibration); ``columns``: the output CSV's columns
    (time, input, simulated output, the uncalibrated output with a calibration, the measured column);
    ``output_name``: the simulated column's name; ``scores``: the metrics against the measured column (None
    without one; with a calibration they cover the samples after the segment, raw and re-anchored);
    ``calibration``: the re-anchoring (None without); ``range_checks``: the model output (`output_check`, last) and the raw and effective input
    against the fitted ranges; ``warnings`` / ``notes``: what was logged, as text; ``record`` and
    ``model`` (the one simulated); ``out`` / ``metrics_file``: the files written (None when not asked).
    """

    y: np.ndarray
    columns: dict[str, np.ndarray]
    output_name: str
    measured: str | None
    scores: dict | None
    calibration: dict | None
    range_checks: list[dict]
    warnings: list[str]
    notes: list[str]
    record: Record
    model: Any
    out: Path | None
    metrics_file: Path | None


def parse_segment(text: str | Sequence[float | None], option: str = "calibrate") -> tuple[float | None, float]:
    """``"START:END"`` (seconds; START may be empty = the record's start) or ``(start, end)`` -> ``(start, end)``."""
    if not isinstance(text, str):
        try:
            start, end = text
            return (None if start is None else float(start)), float(end)
        except (TypeError, ValueError):
            raise UserInputError(f"{option} {text!r}: expected (start, end) in seconds, e.g. (0, 30)") from None
    parts = text.split(":")
    if len(parts) != 2 or not parts[1].strip():
        raise UserInputError(f"{option} {text!r}: expected START:END in seconds, e.g. 0:30")
    try:
        start = float(parts[0]) if parts[0].strip() else None
        end = float(parts[1])
    except ValueError:
        raise UserInputError(f"{option} {text!r}: START and END must be numbers of seconds, e.g. 0:30") from None
    return start, end


def _label(source) -> str:
    if isinstance(source, (str, os.PathLike)):
        return str(source)
    path = getattr(source, "path", None)
    return str(path) if path else f"<{type(source).__name__} object>"


def _columns(rec) -> dict:
    """The record's columns other than time and input, by name (a `Record` loaded with an output has it in ``y``)."""
    cols = dict(rec.extra)
    if rec.y is not None and rec.output_name:
        cols.setdefault(rec.output_name, rec.y)
    return cols


def training_record_start(doc: Mapping, rec) -> dict | None:
    """The fitted start of ``rec`` when it is one of the training records of a joint fit (same file content, fit.json
    ``data.records[].sha256``) that gave each record its own start (``per_record_start[].u0_V``); else None."""
    records = (doc.get("data") or {}).get("records") or []
    sha = rec.sha256
    name = next((r.get("name") for r in records if sha and r.get("sha256") == sha), None)
    if name is None:
        return None
    return next((row for row in doc.get("per_record_start") or [] if row.get("record") == name and "u0_V" in row), None)


def started_as_in_fit(model: Any, row: Mapping) -> Any:
    """``model`` started as one training record of its joint fit: ``row`` is that record's fit.json
    ``per_record_start`` entry (`training_record_start`), its ``u0_V`` and operator-memory rule."""
    model = model.with_thermal_start("given", row["u0_V"])
    if row.get("memory"):
        model = model.with_hysteresis(model.hysteresis.with_init(row["memory"]))
    return model


def _start_note(rule: str, start: Mapping, dt: float | None = None) -> str:
    """``initial state RULE: <thermal start in volts and words>, <operator memory>`` (`with_initial_state`'s info); an
    estimate also says how many starts it compared, over how long, and how the start as fitted did there (a new-user
    trial read an estimate that kept the fitted start as "estimate did nothing")."""
    parts = [start[k] for k in ("thermal_description", "memory_description") if start.get(k)]
    text = f"initial state {rule}" + (f": {', '.join(parts)}" if parts else "")
    rows = start.get("candidates") or []
    if rows and dt:
        best = min(r["rmse_first"] for r in rows)
        fitted = next((r["rmse_first"] for r in rows if r["thermal"] == "fit" and r["memory"] == "as fitted"), None)
        text += (
            f" (the best of {len(rows)} starts, thermal state x operator memory, on the first "
            f"{start['window_samples'] * dt:.4g} s: RMSE there {best:.4g}"
            + (f", the start as fitted {fitted:.4g}" if fitted is not None else "")
            + ")"
        )
    return text


def _is_training_record(doc: Mapping, rec) -> bool:
    """Whether ``rec`` (by file content) is the record, or one of the records, ``doc``'s fit was trained on."""
    data = doc.get("data") or {}
    shas = {data.get("sha256"), *(r.get("sha256") for r in data.get("records") or [])} - {None}
    return bool(rec.sha256) and rec.sha256 in shas


def new_record_start_note(doc: Mapping, model: Any, rec, option: str = "initial_state") -> str | None:
    """The note saying which start a record that is NOT a training record of the fit gets under the rule ``fit``.

    Why: a fit stores the start of *its* record(s); a new record that starts otherwise (warm after an earlier run) is
    then simulated from the wrong state without a word (new-user trial: a joint fit's shared cold start, 0.3 V, on a
    record that started warm: 49.6x the noise, 100x over the first minute).  None for a training record or a model
    given without its fit.json.
    """
    from ..models._initial_state import _memory_words, _start_words

    if not doc or _is_training_record(doc, rec):
        return None
    start = _start_words(model, "fit", float(rec.u[0]), None)
    v = start.get("u0_V")
    which = next(
        (r["record"] for r in doc.get("per_record_start") or [] if v is not None and np.isclose(r.get("u0_V", np.nan), v)), None
    )
    thermal = start.get("thermal_description")
    if thermal and which:
        thermal = thermal.replace("(as fitted)", f"(the fitted start of training record {which})")
    parts = [x for x in (thermal, _memory_words(model) if getattr(model, "hysteresis", None) is not None else None) if x]
    if not parts:
        return None
    return (
        f"initial state fit: {rec.name} is not a training record of this fit, so it starts as the fit did: {', '.join(parts)}; "
        f"if it starts otherwise (e.g. warm after an earlier run), use {option} estimate (the start that best matches the "
        "measured column's first part), steady (at rest with the first input) or cold"
    )


def _bridged(y: np.ndarray) -> tuple[np.ndarray, int]:
    """``y`` with its non-finite cells filled by linear interpolation between finite neighbours, and how many."""
    bad = ~np.isfinite(y)
    idx = np.arange(y.size)
    return np.where(bad, np.interp(idx, idx[~bad], y[~bad]), y), int(bad.sum())


#: A measured output whose range differs from the model's (the fitted record's, and the model's output on this record)
#: by more than this factor either way gets a unit warning: metres scored against a model in millimetres (new-user trial:
#: RMSE 2.65, 3.99e+05x the noise, no hint).  10x: a drive smaller than the training's moves less, but the model's own
#: output on the same drive moves less too, so the two ratios together separate units from amplitude.
UNIT_RATIO_WARN = 10.0


def fitted_output_span(doc: Mapping) -> float | None:
    """The output range (max - min) of the fitted record(s): fit.json ``data.output_range`` when it has one, else
    recovered from the fit's metrics (eq. 3: e_r = max|error| / range), None when neither is there."""
    rng = (doc.get("data") or {}).get("output_range")
    if isinstance(rng, (list, tuple)) and len(rng) == 2:
        return float(rng[1]) - float(rng[0])
    for part in ("whole_record", "train"):
        m = (doc.get("metrics") or {}).get(part) or {}
        e, mx = m.get("e_r_percent"), m.get("max_abs_error")
        if isinstance(e, (int, float)) and isinstance(mx, (int, float)) and np.isfinite(e) and e > 0:
            return float(mx) * 100.0 / float(e)
    return None


def output_scale_check(measured: np.ndarray, simulated: np.ndarray, fitted_span: float | None, column: str) -> dict:
    """The measured output's range against the fitted output range and the model's output range on this record, with a
    ``warning`` (possible unit mismatch) when it differs from every known one by more than `UNIT_RATIO_WARN` the same
    way."""
    span_m = float(np.ptp(measured)) if measured.size else 0.0
    span_s = float(np.ptp(simulated))
    out = {"measured_range": span_m, "model_output_range": span_s, "fitted_output_range": fitted_span}
    refs = {"fitted": fitted_span, "model_output": span_s}
    ratios = {k: span_m / v for k, v in refs.items() if v is not None and v > 0 and span_m > 0}
    out["ratios"] = ratios
    out["warn_factor"] = UNIT_RATIO_WARN
    if not ratios:
        return out
    big = all(r > UNIT_RATIO_WARN for r in ratios.values())
    small = all(r < 1.0 / UNIT_RATIO_WARN for r in ratios.values())
    if big or small:
        r = ratios.get("fitted", ratios.get("model_output"))
        fitted = f", the fitted record's output {fitted_span:.4g}" if fitted_span is not None else ""
        out["warning"] = (
            f"possible unit mismatch: the measured column '{column}' spans {span_m:.4g} and the model's output on this record "
            f"{span_s:.4g}{fitted} ({r:.3g}x); check the column's units (metres against a model in millimetres reads 1000x "
            "smaller): the scores compare different units"
        )
    return out


#: `output_sign_check` warns when the measured column anti-correlates with the model's output at least this strongly ...
SIGN_CORR_WARN = -0.5
#: ... and the sign-flipped model (with its best offset) fits it at most this fraction of the RMSE as read.
SIGN_RMSE_RATIO = 0.5


def output_sign_check(
    measured: np.ndarray, simulated: np.ndarray, column: str, option: str, sign: int = 1, calibrate_option: str = "--calibrate"
) -> dict:
    """Whether the measured column reads the other way from the model's output: their correlation, and the RMSE (each
    with its best constant offset) of the model as read and sign-flipped, with a ``warning`` naming a reversed sensor
    when the flipped model fits far better.  Why: a new-user trial scored a sensor read as ``85 - y`` at 1.6e4x the
    noise with no hint, and a calibration on it ended at its bounds."""
    m, s = np.asarray(measured, np.float64), np.asarray(simulated, np.float64)
    out: dict = {"rule": f"correlation <= {SIGN_CORR_WARN} and flipped RMSE <= {SIGN_RMSE_RATIO} x as read (offsets removed)"}
    if m.size < 3 or np.ptp(m) == 0 or np.ptp(s) == 0:
        return {**out, "checked": False}
    r = float(np.corrcoef(m, s)[0, 1])
    as_read, flipped = float(np.std(m - s)), float(np.std(m + s))
    out.update(checked=True, correlation=r, rmse_offset_removed=as_read, rmse_flipped_offset_removed=flipped)
    if r <= SIGN_CORR_WARN and flipped <= SIGN_RMSE_RATIO * as_read:
        how = (
            f"drop {option} -1: the column may read the right way as it is"
            if sign == -1
            else f"rerun with {option} -1 (and {calibrate_option} START:END, or output_offset, for the sensor's own zero), or refit "
            "on records read this way"
        )
        read = "flipped as asked" if sign == -1 else "as read"
        out["warning"] = (
            f"the measured column '{column}' ({read}) runs against the model's output (correlation {r:.3f}): flipped and "
            f"offset, the model would score RMSE {flipped:.4g} against {as_read:.4g} {read}; a sensor mounted or wired "
            f"the other way (a length sensor read as extension, or c - y) would do this: {how}"
        )
    return out


#: `output_offset_check` warns when the mean error carries at least this share of the mean squared error ...
OFFSET_SHARE = 0.75
#: ... and is at least this many noise SDs.
OFFSET_NOISE = 5.0


def output_offset_check(
    measured: np.ndarray,
    simulated: np.ndarray,
    noise_sd: float | None,
    column: str,
    calibrate_option: str = "--calibrate",
    calibrate_fit_option: str = "--calibrate-fit",
) -> dict:
    """Whether the error is mostly one constant offset: the mean of ``measured - simulated``, its share of the mean
    squared error and the RMSE without it, with a ``warning`` naming the sensor's zero when the offset dominates.  Why: a
    new-user trial (an independent plant, a length sensor re-zeroed 8.4 mm away between runs) scored a new run at 596x the
    noise with only small range warnings beside it, which a user would blame; without the offset 13.3x was left."""
    e = np.asarray(measured, np.float64) - np.asarray(simulated, np.float64)
    out: dict = {"rule": f"mean error >= {OFFSET_SHARE:g} of the mean squared error and >= {OFFSET_NOISE:g} noise SDs"}
    if e.size < 3 or noise_sd is None or not np.isfinite(noise_sd) or noise_sd <= 0:
        return {**out, "checked": False}
    bias, mse = float(np.mean(e)), float(np.mean(e**2))
    share = bias**2 / mse if mse > 0 else 0.0
    rest = float(np.std(e))
    out.update(checked=True, mean_error=bias, share_of_mse=share, rmse_offset_removed=rest)
    if share >= OFFSET_SHARE and abs(bias) >= OFFSET_NOISE * noise_sd:
        out["warning"] = (
            f"the error is mostly one constant offset: '{column}' reads {bias:+.4g} from the model on average ({100 * share:.0f} % "
            f"of the mean squared error; without it the RMSE would be {rest:.4g}, {rest / noise_sd:.3g}x the noise): a "
            f"sensor zeroed elsewhere (a re-zeroed length sensor, a tare) would do this; {calibrate_option} START:END "
            f"{calibrate_fit_option} output_offset re-anchors the output on a segment of this record"
        )
    return out


def _out_name(output_name: str | None, data_info: Mapping) -> str:
    """The simulated column's name: ``output_name``, else ``<the fit's output column>_model``."""
    return output_name or f"{data_info.get('output_column') or 'output'}_model"


def worse_after_segment(after: Mapping, calibration: Mapping, raw_name: str) -> str | None:
    """The warning when the re-anchored output scores a higher RMSE than the raw model's on the measured samples after
    the calibration segment (`after_segment_metrics`), else None.

    Why: the calibration is fitted on its segment only and cannot know the rest of the run; a cross-run trial re-anchored
    on 0-30 s lowered the segment RMSE 4.87 -> 2.12 and raised it after the segment 4.52 -> 4.60 (e_r 57 -> 94 %).  This
    is a score of the measured output, not used in the fit.
    """
    raw, cal = after["raw"], after["recalibrated"]
    if not cal["rmse"] > raw["rmse"]:
        return None
    why = []
    if calibration.get("at_bound"):
        why.append(f"{', '.join(calibration['at_bound'])} at its bound")
    if not calibration.get("converged", True):
        why.append("the refinement did not converge")
    return (
        f"calibration made the prediction worse after the segment: RMSE {raw['rmse']:.4g} (raw) -> {cal['rmse']:.4g} "
        f"(re-anchored), e_r {raw['e_r_percent']:.3g} -> {cal['e_r_percent']:.3g} % on the {cal['n_samples']} measured samples "
        f"from {calibration['scored_from_s']:.6g} s, though it lowered the segment's own RMSE "
        f"{calibration['segment_rmse_before']:.4g} -> {calibration['segment_rmse_after']:.4g}"
        + (f" ({'; '.join(why)})" if why else "")
        + f": what the segment fitted does not carry over to the rest of this run; the raw prediction is column '{raw_name}' "
        "(try a longer segment or the output offset alone)"
    )


def simulate_record(
    model: PathLike | Any,
    record: PathLike | Record,
    *,
    out: PathLike | None = None,
    metrics_file: PathLike | None = None,
    input: str | None = None,
    time: str | None = None,
    output_name: str | None = None,
    measured: str | None = None,
    resample: float | str | None = None,
    initial_state: str = "fit",
    method: str | None = None,
    calibrate: str | Sequence[float | None] | None = None,
    calibrate_fit: str | Sequence[str] | None = None,
    measured_sign: int = 1,
    option_names: Mapping[str, str] | None = None,
) -> SimulationResult:
    """Run ``model`` on ``record``; write the output CSV to ``out`` and the scores to ``metrics_file`` (each if given).

    ``model``: a model file or fit.json path (its input / output columns, sample time and fitted input
    ranges are the defaults and the range checks) or a model object.  ``record``: a CSV path (``input``
    picks the input column, ``time`` the time column; ``resample``: None, seconds or ``"auto"`` for irregular time stamps) or a
    `Record`.  ``measured``: the measured output column to score against (default the fit's output
    column when present).  ``initial_state``: ``fit``, ``steady``, ``cold`` or ``estimate`` (from the
    measured column).  ``method``: the evaluation form (``auto``, ``scan``, ``assoc``, ``chunked``,
    ``segmented``; default the model's own).  ``calibrate``: ``"START:END"`` or ``(start, end)`` seconds of
    the record on which to re-anchor the model (``calibrate_fit``: which of input_gain, input_offset,
    output_offset, comma-separated or a sequence; default all); the scores then cover only the samples
    after the segment.  ``measured_sign``: -1 reads the measured column with its sign flipped (a sensor that reads
    the other way; the scores, the start estimate and the calibration use the flipped column, the CSV keeps it as
    read).  ``metrics_file`` needs a measured column.  An existing ``out`` file is replaced
    (logged as a note).  ``option_names``: how error messages name the settings.
    """
    from .._io import atomic_write_csv, atomic_write_json, check_writable_file, load_model_file
    from ..data._data import Record, load_record, parse_resample
    from ..models._simulate import simulate

    o = option_namer(option_names)
    warnings: list[str] = []
    notes: list[str] = []

    def note(text):
        notes.append(text)
        LOGGER.info(f"note: {text}")

    def warn(text):
        warnings.append(text)
        LOGGER.warning(text)

    if out is not None:
        check_writable_file(out)  # before the simulation: a bad path fails at once
    segment = parse_segment(calibrate, o("calibrate")) if calibrate is not None else None
    if calibrate_fit is not None and segment is None:
        raise UserInputError(f"{o('calibrate_fit')} needs {o('calibrate')} START:END")
    fit_names = None
    if segment is not None:
        from ..identify._recalibrate import _check_fit_names

        names = calibrate_fit if calibrate_fit is not None else CALIBRATION_DEFAULT
        if isinstance(names, str):
            names = names.split(",")
        fit_names = _check_fit_names([n.strip() for n in names if n.strip()])
    if initial_state not in INITIAL_STATES:
        raise UserInputError(f"{o('initial_state')} must be one of {INITIAL_STATES}, got {initial_state!r}")
    if metrics_file is not None:
        check_writable_file(metrics_file, "metrics file")
    model_label, data_label = _label(model), _label(record)
    if isinstance(model, (str, os.PathLike)):
        model, doc = load_model_file(model)
    else:
        doc = {}
    if method is not None:
        from ..models._operators import model_with_method

        try:
            model = model_with_method(model, method)
        except ValueError as exc:
            raise UserInputError(f"{model_label}: {o('method')} {method}: {exc}") from None
    data_info = doc.get("data", {}) if isinstance(doc.get("data"), dict) else {}
    if isinstance(record, Record):
        if input is not None or time is not None or resample is not None:
            raise UserInputError("input / time / resample apply to a CSV; a Record given as the data is loaded already")
        rec = record
    elif isinstance(record, (str, os.PathLike)):
        in_col = input or data_info.get("input_column")
        # the measured column is optional: loaded as the output, blank cells come back as NaN (left out of the scores)
        out_col = measured or data_info.get("output_column")
        rec = load_record(
            record, input=in_col, output=out_col, time=time, require_output=False, min_samples=2,
            resample=parse_resample(resample),
        )  # fmt: skip
    else:
        raise UserInputError(f"record: expected a CSV path or a Record, got a {type(record).__name__}")
    for text in rec.processing:
        note(f"loading {rec.name}: {text}")
    fit_dt = data_info.get("sample_time_s")
    if fit_dt and not np.isclose(fit_dt, rec.dt, rtol=0.02):
        note(
            f"the model was fitted at dt={fit_dt:g} s and this record has dt={rec.dt:g} s; "
            "the thermal part accounts for it, a rate-independent EUPI does not care"
        )
    cols_in = _columns(rec)
    measured_col = measured or data_info.get("output_column")
    cols_as_read = dict(cols_in)
    if measured_sign not in (1, -1):
        raise UserInputError(f"{o('measured_sign')} must be 1 or -1, got {measured_sign!r}")
    if measured_sign == -1:
        if measured_col not in cols_in:
            raise UserInputError(
                f"{o('measured_sign')} -1 needs the measured output column in {data_label} (see {o('measured')}); "
                f"columns: {sorted(cols_in)}"
            )
        cols_in[measured_col] = -np.asarray(cols_in[measured_col], dtype=np.float64)
        note(
            f"reading '{measured_col}' with its sign flipped ({o('measured_sign')} -1): the scores"
            f"{', the calibration' if segment is not None else ''} and any start estimate use -{measured_col}; the output "
            "CSV keeps the column as read"
        )
    if initial_state != "fit":
        from ..models._initial_state import with_initial_state

        y_meas = np.asarray(cols_in[measured_col], dtype=np.float64) if measured_col in cols_in else None
        if initial_state == "estimate" and y_meas is not None and 0 < np.sum(~np.isfinite(y_meas)) < y_meas.size - 1:
            y_meas, n_filled = _bridged(y_meas)
            note(f"estimating the start: {n_filled} blank/NaN cell(s) of '{measured_col}' bridged by linear interpolation")
        model, start = with_initial_state(model, initial_state, rec.u, y_meas, rec.dt)
        note(_start_note(initial_state, start, rec.dt))
    elif (own := training_record_start(doc, rec)) is not None:
        # a training record of a joint fit: its own fitted start, not the shared rule the saved model carries
        model = started_as_in_fit(model, own)
        memory = f", {own['memory']} operator memory" if own.get("memory") else ""
        note(
            f"initial state fit: {rec.name} is training record {own['record']} of the joint fit: its own start, {own['u0_V']:.4g} V{memory}"
        )
    elif (text := new_record_start_note(doc, model, rec, o("initial_state"))) is not None:
        note(text)
    if measured and measured_col not in cols_in:
        raise UserInputError(f"{data_label}: no column {measured_col!r} to score against; columns: {sorted(cols_in)}")
    calibration = None
    raw_model = model
    if segment is not None:
        from ..identify._recalibrate import NOT_IMPROVED, recalibrate

        if measured_col not in cols_in:
            raise UserInputError(
                f"{o('calibrate')} needs the measured output column in {data_label} (see {o('measured')}); "
                f"columns: {sorted(cols_in)}"
            )
        model, calibration = recalibrate(
            model,
            rec.u,
            np.asarray(cols_in[measured_col], dtype=np.float64),
            rec.dt,
            segment,
            fit=fit_names,
            t0=float(rec.time[0]),
            log_warnings=False,  # said once, below, with the workflow's other warnings
        )
        if metrics_file is not None and calibration["scored_from_sample"] >= len(rec):
            raise UserInputError(
                f"{o('calibrate')} {calibrate}: the segment reaches the end of the record, so nothing after it is left to score"
            )
        seg = calibration["segment"]
        LOGGER.debug(  # the command line prints this line from the result
            f"calibration on {seg['start_s']:.6g}-{seg['end_s']:.6g} s ({seg['n_samples']} samples, fitted: "
            f"{', '.join(calibration['fitted'])}): input_gain {calibration['input_gain']:.6g}, input_offset "
            f"{calibration['input_offset']:.6g}, output_offset {calibration['output_offset']:.6g}; segment RMSE "
            f"{calibration['segment_rmse_before']:.4g} -> {calibration['segment_rmse_after']:.4g}"
        )
        for text in calibration["warnings"]:  # at a bound, not converged, no better on its own segment
            if text.startswith(NOT_IMPROVED):
                text += (
                    "; the re-anchored output is written as asked, and the raw model's beside it (column "
                    f"'{_out_name(output_name, data_info)}_uncalibrated')"
                )
            warn(text)
    from ..models._range import model_range_checks, output_check

    t0 = float(rec.time[0])  # warnings and JSON on the record's own time axis (a record starting at 1000 s says 1026.6 s)
    if calibration is None:
        checks = model_range_checks(model, data_info, rec.u, rec.dt, rec.input_name, t0=t0)
    else:  # the wrapped model sees the re-anchored input: that is the one to hold against the fitted range
        u_seen = np.asarray(model.model_input(np.asarray(rec.u, dtype=np.float64)))
        checks = model_range_checks(model.model, data_info, u_seen, rec.dt, f"{rec.input_name} (re-anchored)", t0=t0)
    for chk in checks:
        if chk.get("warning"):
            warn(chk["warning"])
        elif chk.get("note"):
            note(chk["note"])
    y = np.asarray(simulate(model, rec.u, rec.dt))
    if not np.all(np.isfinite(y)):
        raise UserInputError(f"{model_label}: the model produced non-finite output on {data_label}")
    # the raw model's output, before any re-anchoring: that is what the fitted output range describes
    inside = not any(c.get("warning") for c in checks if c.get("what") in ("input", "effective input"))
    y_raw = y if calibration is None else np.asarray(simulate(raw_model, rec.u, rec.dt))
    out_chk = output_check(y_raw, data_info.get("output_range"), input_inside=inside, dt=rec.dt, t0=t0)
    checks.append(out_chk)
    if out_chk.get("warning"):
        warn(out_chk["warning"])
    elif out_chk.get("note") and out_chk.get("checked"):
        note(out_chk["note"])
    out_name = _out_name(output_name, data_info)
    if out_name in ("time_s", rec.input_name):
        raise UserInputError(f"{o('output_name')} {out_name!r} clashes with an input column")
    cols = {"time_s": rec.time, rec.input_name: rec.u, out_name: y}
    scores = None
    if calibration is not None:
        raw_name = f"{out_name}_uncalibrated"
        if raw_name in (rec.input_name, measured_col):
            raise UserInputError(
                f"{o('output_name')} {out_name!r}: the uncalibrated column {raw_name!r} clashes with a data column"
            )
        cols[raw_name] = y_raw
    if measured_col in cols_in and measured_col != out_name:
        from ..identify._metrics import metrics

        ym = np.asarray(cols_in[measured_col], dtype=np.float64)
        # blank / NaN measured cells (an optional column with gaps) are left out of every score, and kept in the CSV
        finite = np.isfinite(ym)
        n_left = int(ym.size - finite.sum())
        k_cal = calibration["scored_from_sample"] if calibration is not None else 0
        if k_cal < len(rec) and not finite[k_cal:].any():
            warn(
                f"the measured column '{measured_col}' has no finite value{' after the segment' if k_cal else ''}: nothing scored"
            )
        elif calibration is None:
            scores = {"measured_column": measured_col, **metrics(ym[finite], y[finite])}
        elif k_cal < len(rec):
            from ..identify._recalibrate import after_segment_metrics

            after = after_segment_metrics(ym[finite], y_raw[finite], y[finite], int(finite[:k_cal].sum()))
            if (text := worse_after_segment(after, calibration, raw_name)) is not None:
                warn(text)
            scores = {
                "measured_column": measured_col,
                "scored_from_s": calibration["scored_from_s"],
                "scored_from_sample": calibration["scored_from_sample"],
                **after["recalibrated"],
                "raw_after_segment": after["raw"],
                "recalibrated_after_segment": after["recalibrated"],
            }
        if scores is not None:  # the error over the measured output's own noise: 1x = only the noise is left
            from ..identify._metrics import noise_floor

            # the record's measured column with its gaps: blank cells and samples interpolated across a resampling gap
            # are left out of the noise estimate (a straight line has no noise)
            # (a resampled record's noise is read on its stamps as read: the measured column there, signed as scored)
            raw = rec.as_read
            raw_col = None if raw is None else _columns(raw).get(measured_col)
            as_read = (
                None if raw_col is None else dataclasses.replace(raw, y=measured_sign * np.asarray(raw_col, dtype=np.float64))
            )
            scores["noise"] = noise_floor([dataclasses.replace(rec, y=ym, as_read=as_read)], scored={"rmse": scores["rmse"]})
            if n_left:
                scores["n_left_out"] = n_left
                scores["left_out_rule"] = "blank / NaN measured cells: left out of every score (kept in the output CSV)"
                note(
                    f"scoring against '{measured_col}' on its {int(finite.sum())} finite samples: {n_left} blank/NaN "
                    "sample(s) left out of the score"
                )
            scale = output_scale_check(ym[finite], y[finite], fitted_output_span(doc), measured_col)
            scores["output_scale_check"] = scale
            if scale.get("warning"):
                warn(scale["warning"])
            # the raw model's output: a calibration fitted on a reversed column cannot flip it, only distort it
            sign = output_sign_check(ym[finite], (y_raw if calibration is not None else y)[finite], measured_col,
                                     o("measured_sign"), measured_sign, o("calibrate"))  # fmt: skip
            scores["output_sign_check"] = sign
            if sign.get("warning"):
                warn(sign["warning"])
            elif calibration is None:  # a reversed column is its own finding; a calibration fits the offset already
                offset = output_offset_check(ym[finite], y[finite], scores["noise"].get("sd"), measured_col,
                                             o("calibrate"), o("calibrate_fit"))  # fmt: skip
                scores["output_offset_check"] = offset
                if offset.get("warning"):
                    warn(offset["warning"])
        cols[measured_col] = cols_as_read[measured_col]
    if metrics_file is not None and scores is None:  # checked before anything is written
        raise UserInputError(f"{o('metrics_file')} needs a measured output column in the CSV (see {o('measured')})")
    if out is not None:
        out = Path(out)
        if out.exists():
            note(f"replacing existing {out}")
        atomic_write_csv(out, cols)
    if metrics_file is not None:
        metrics_file = Path(metrics_file)
        atomic_write_json(
            metrics_file,
            {
                "model": model_label,
                "data": data_label,
                "n_samples": len(rec),
                **scores,  # with a calibration its n_samples counts the scored samples after the segment
                **({"n_record_samples": len(rec), "calibration": calibration} if calibration is not None else {}),
                "input_range_check": checks[0],
                "effective_input_range_check": next((c for c in checks[1:] if c.get("what") == "effective input"), None),
                "branch_check": next((c for c in checks if c.get("what") == "branches"), None),
                "output_range_check": out_chk,
                "processing": list(rec.processing),
                "measured_sign": measured_sign,
            },
        )
    return SimulationResult(
        y=y,
        columns=cols,
        output_name=out_name,
        measured=measured_col if scores is not None else None,
        scores=scores,
        calibration=calibration,
        range_checks=checks,
        warnings=warnings,
        notes=notes,
        record=rec,
        model=model,
        out=out,
        metrics_file=metrics_file,
    )
