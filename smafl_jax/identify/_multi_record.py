"""Several records, one model: joint fit, leave-one-record-out validation, baselines and data checks.

`fit_records` fits one model to several records at once (each record runs
from its own initial state; `smafl_jax.fit` takes the list) with the same
model choice as `fit_record` (structure, start screening, trainable set).
With two or more records it validates by leave-one-record-out (LORO): fold i
refits on all records but i, from scratch (the start model is built on the
training records' input range only), and scores record i whole, simulated
from its own first sample.  The two baselines of `smafl_jax.identify._baselines` are
fitted and scored on the same folds.  The headline is the mean over folds of
the held-out RMSE and e_r (eq. 3, per held-out record's output range); the
model that is kept and written is the joint fit on all records.  The
verdict against a baseline (`loro_sentences`) needs both a lower mean RMSE
and a lower RMSE on more than half of the held-out records, so that one badly
predicted record (input spikes, an odd run) cannot decide it either way.

Also here: the data-check section of a fit (`data_checks_doc`,
`data_checks_markdown`; the checks are those of `smafl check`) and
`add_record_extras`, which adds baselines, data checks, loading notes and the
training input range to a one-record fit.json.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from .._blas import blas_limited
from .._errors import UserInputError
from .._progress import format_seconds
from .._progress import say as progress_line
from ..models._hysteresis import hysteresis_of, record_model, thermal_of
from ..models._range import value_range
from ._baselines import BASELINES, TIE_RATIO, baselines_doc, baselines_markdown, compare_sentences, is_voltage
from ._baselines import TITLES as BASELINE_TITLES
from ._gain_prior import GAIN_PRIOR
from ._hold import check_hold_input, hold_choice, hold_fitted, hold_on
from ._metrics import metrics, noise_floor, noise_floor_note
from ._split import interpolated_note

__all__ = [
    "fit_records",
    "write_records_outputs",
    "data_checks_doc",
    "data_checks_markdown",
    "add_record_extras",
    "start_mismatch",
    "START_MISMATCH",
]

log = logging.getLogger(__name__)


def _axis_label(name, units):
    from ..report._reportdoc import axis_label

    return axis_label(name, units)


#: Findings listed one by one in a report; the rest are counted (all are in fit.json).
MAX_FINDING_LINES = 20
#: Options of `fit_record` that `fit_records` takes (``split``: ``"auto"`` = LORO with >= 2 records, ``"none"`` = no LORO).
FIT_OPTIONS = (
    "split",
    "val_fraction",
    "solver",
    "max_steps",
    "thresholds",
    "tilts",
    "grid",
    "orientation",
    "thermal_start",
    "sees",
    "gain_prior",
    "hold_input",
)


# -- data checks ------------------------------------------------------------------------


def data_checks_doc(records) -> dict:
    """fit.json ``"data_checks"``: the findings of `smafl_jax.data.check_records` (rules there), with counts."""
    from ..data.checks import check_records

    recs = [records] if hasattr(records, "u") else list(records)
    findings = check_records(recs)
    return {
        "rule": "smafl_jax.data.checks (as `smafl check`); nothing was changed in the data because of a finding",
        "n_findings": len(findings),
        "counts": dict(Counter(f.kind for f in findings)),
        "findings": [f.to_dict() for f in findings],
    }


def data_checks_markdown(dc: dict | None) -> list[str]:
    """Report lines for the data-check section."""
    if dc is None:
        return []
    lines = ["", "## Data checks", ""]
    if not dc["n_findings"]:
        return lines + ["No findings (offset jumps, spikes, flat or clipped stretches, sampling, levels across records)."]
    counts = ", ".join(f"{n} {k}" for k, n in sorted(dc["counts"].items()))
    lines += [f"{dc['n_findings']} finding(s): {counts}. Nothing was changed; the suggested actions are the user's call.", ""]
    for f in dc["findings"][:MAX_FINDING_LINES]:
        t0, t1 = f["time_s"]
        size = "" if f["size"] is None else f", size {f['size']:+.4g}"
        lines.append(
            f"- `{f['record']}` **{f['kind']}** [{f['column']}] t {t0:.6g}-{t1:.6g} s{size} -> {f['action']}: {f['message']}"
        )
    if dc["n_findings"] > MAX_FINDING_LINES:
        lines.append(f"- ... and {dc['n_findings'] - MAX_FINDING_LINES} more (all in fit.json)")
    return lines


def _input_range(records, masks=None) -> list[float]:
    """`value_range` of the input over several records (each over its mask when given)."""
    masks = masks or [None] * len(records)
    return value_range(np.concatenate([np.asarray(r.u)[m] if m is not None else np.asarray(r.u) for r, m in zip(records, masks)]))


#: fit.json ``data.output_range_rule``.
OUTPUT_RANGE_RULE = "min and max of the measured output over the samples the saved model was fitted on"


def train_output_mask(record) -> np.ndarray:
    """The samples of ``record`` whose output was measured and is finite (not bridged across a resampling gap)."""
    y = np.asarray(record.y, dtype=np.float64)
    return np.isfinite(y) & np.asarray(getattr(record, "measured", np.ones(y.shape, bool)), bool)


def add_record_extras(
    doc: dict, record, train: np.ndarray, val: np.ndarray, yhat: np.ndarray, fitted_on: np.ndarray | None = None
) -> dict:
    """Add to a one-record fit.json: training input range, loading notes, baselines and data checks (in place).

    ``fitted_on``: the samples the SAVED model was fitted on (default ``train``; the whole record after the refit),
    which is the range `smafl simulate` checks a new drive against; the baselines use the split (``train`` / ``val``).
    """
    whole = fitted_on is not None and bool(np.all(fitted_on))
    doc["data"]["input_range"] = _input_range([record], [train if fitted_on is None else fitted_on])
    doc["data"]["input_range_rule"] = (
        "min and max of the input over the whole record (the saved model was refitted on it)"
        if whole
        else "min and max of the input over the training samples (the range the model was fitted on)"
    )
    on = (np.ones(len(record), bool) if fitted_on is None else np.asarray(fitted_on, bool)) & train_output_mask(record)
    if fitted_on is None:
        on &= np.asarray(train, bool)
    if on.any():  # what the saved model was fitted to reach: `simulate` warns when its output leaves that far
        doc["data"]["output_range"] = value_range(record.y, on)
        doc["data"]["output_range_rule"] = OUTPUT_RANGE_RULE
    doc["data"]["processing"] = list(getattr(record, "processing", ()) or ())
    model_val = doc["metrics"].get("validation")
    doc["baselines"] = baselines_doc(
        [record], [train], [record], [val], squared=is_voltage(record.input_name, record.units), model_heldout=model_val
    )
    doc["baselines"]["heldout_kind"] = "the fit's validation samples"
    doc["data_checks"] = data_checks_doc([record])
    return doc


# -- joint fit --------------------------------------------------------------------------


def _combined(records):
    """One record holding all samples back to back: only for the model choice and its input range (never simulated)."""
    cat = lambda xs: np.concatenate([np.asarray(x, dtype=np.float64) for x in xs])
    return dataclasses.replace(
        records[0],
        time=np.arange(sum(len(r) for r in records), dtype=np.float64),
        u=cat([r.u for r in records]),
        y=cat([r.y for r in records]),
        extra={},
    )


def _joint_fit(
    records, *, model, solver, max_steps, thresholds, tilts, grid, orientation, thermal_start, sees="auto", gain_prior=None,
    progress,
):  # fmt: skip
    """The model choice of `fit_record` on several records (all samples train); returns ``(FitResult, info)``."""
    from ..report._report_fit import joint_steps, structure_start
    from ._choose import screen_start
    from ._fit import default_trainable, fit

    combo = _combined(records)
    structure, thresholds, tilts, start, notes = structure_start(model, combo, thresholds, tilts, grid)
    max_steps = joint_steps(start, max_steps, notes)
    weights = [r.measured.astype(float) for r in records]  # samples a resampling interpolated carry no weight
    screening, init, screen_info = None, "auto", {}
    if hysteresis_of(start) is not None:  # as `fit_record`: every model with a hysteresis part is screened
        # each record its own thermal start (`screen_start(record_starts=True)`, `smafl_jax.identify._record_starts`)
        start, screening, screen_info = screen_start(
            start, list(records), weights, orientation=orientation, thermal_start=thermal_start, sees=sees,
            record_starts=True, progress=progress,
        )  # fmt: skip
        init = None  # the screened start is already profiled
    record_starts = screen_info.get("record_starts") if thermal_of(start) is not None else None
    spec = default_trainable(start, thresholds=thresholds, tilts=tilts)
    res = fit(
        start,
        list(records),
        solver=solver,
        trainable=spec,
        init=init,
        weights=weights,
        max_steps=max_steps,
        gain_prior=gain_prior,
        progress=progress,
    )
    info = {
        "structure": structure,
        "notes": notes,
        "screening": screening,
        "profile": (res.info or {}).get("profile") or screen_info.get("profile") or {},
        "thresholds": thresholds,
        "tilts": tilts,
        "record_starts": record_starts,  # per-record thermal starts of the screening (None: one rule for all)
    }
    return res, info


def _with_shared_start(model, info):
    """``model`` (a joint fit, maybe with one thermal start per record) started by the screening's one shared rule: the
    form saved to fit.json and run on a new record, whose own start is not known."""
    if info.get("record_starts") is None:
        return model
    init, u0 = info["record_starts"]["shared_rule"]
    return model.with_thermal_start(init, u0)


def _hold_by_folds(runs, rule):
    """Whether the leave-one-record-out folds are scored held or extrapolating (`hold_choice` over the pooled held-out
    squared errors of the folds where the two differ), and the fit.json ``settings.hold_input_check`` entry (None when
    no fold differs)."""
    differ = [(rec, preds) for _, rec, _, _, _, preds, _ in runs if "extrapolating" in preds]
    if not differ:
        return "held", None
    sse = {
        way: sum(float(np.sum((p[way][0][p[way][1]] - rec.y[p[way][1]]) ** 2)) for rec, p in differ)
        for way in ("held", "extrapolating")
    }
    n = sum(int(p["held"][1].sum()) for _, p in differ)
    return hold_choice(sse["held"], sse["extrapolating"], n, rule, "the leave-one-record-out folds")


def _heldout(model, info, rec):
    """``(prediction, scored mask, start info)`` of a fold model on its held-out record.

    A model with a thermal stage starts the held-out record from the start estimated on the record's own first window
    (`estimate_initial_state`: thermal state x operator memory, the best match of the measured output there), and only
    the samples after the window are scored: records of one rig start in different states, which the training records
    cannot tell (measured, session 32: a warm record held out from a cold one's fit, 12.4x the noise from the trained
    start).  ``start["shared_start_whole"]``: the metrics from the trained start over the whole record (the earlier
    rule).  A model without one runs from its fitted start and is scored whole."""
    from ..models._initial_state import estimate_initial_state
    from ..models._simulate import simulate

    shared = _with_shared_start(model, info)
    y_shared = np.asarray(simulate(shared, rec.u, rec.dt))
    if thermal_of(shared) is None:
        return y_shared, rec.measured, {"rule": "the fitted start, scored whole"}
    est, got = estimate_initial_state(shared, rec.u, rec.y, rec.dt)
    scored = (np.arange(len(rec)) >= got["window_samples"]) & rec.measured
    after = int(scored.sum()) >= 10
    if not after:  # a record shorter than its window (5 thermal time constants): nothing would be left to score
        scored = rec.measured
    start = {
        "rule": "estimated from the held-out record's first window (estimate_initial_state), scored after it"
        if after
        else "estimated from the held-out record's first window, which covers the record: scored whole",
        "window_samples": got["window_samples"],
        "thermal": got["thermal"],
        "memory": got["memory"],
        "shared_start_whole": metrics(rec.y[rec.measured], y_shared[rec.measured]) if np.all(np.isfinite(y_shared)) else None,
    }
    return np.asarray(simulate(est, rec.u, rec.dt)), scored, start


#: Start of the note (printed as a warning by `smafl fit`) when records' first time constants are fitted much worse than
#: the rest: the records start in states the one shared start rule does not reach.
START_MISMATCH = "records start in different states:"
#: Window of a record's start (thermal time constants), and the ratio of its RMSE to the rest's that flags it.
START_WINDOW_TAU, START_RATIO = 3.0, 1.5


def start_mismatch(
    records, yhat, k1: float, noise_sd: float, names=None, per_record: bool = False
) -> tuple[list[dict], str | None]:
    """Per record, the joint model's RMSE in its first `START_WINDOW_TAU` thermal time constants (at most 30 % of the
    record) against the RMSE after; the note when some record's start is > `START_RATIO` x its rest and > 2x the noise.

    Why: the joint model has one start rule (and one fitted start temperature) for all records, so a record that starts
    warm among records that start cold is misfitted at its start, and the fit bends the thermal rate to absorb it.
    Measured (session 32, one independent plant, PWM 25 Hz cold + multisine 100 Hz): with the multisine record cold the
    joint fit held its training at 1.01x the noise (leave-one-record-out 2.1x); with it warm 3.41x (12.4x), the fitted
    thermal time constant 131 s instead of 21 s.  Start / rest RMSE ratios: 1.59 and 1.78 on that warm pair, 1.6-7.1 with a
    third record (steps 10 Hz cold), 0.98-1.02 on three pairs that start alike.
    """
    rows, flagged = [], []
    for r, y, name in zip(records, yhat, names or [r.name for r in records]):
        t = np.asarray(r.time, dtype=np.float64) - float(r.time[0])
        window = min(START_WINDOW_TAU / max(float(k1), 1e-12), 0.3 * float(t[-1]))
        early = t < window
        e = np.asarray(y, dtype=np.float64) - np.asarray(r.y, dtype=np.float64)
        if early.sum() < 10 or (~early).sum() < 10:
            continue
        a, b = float(np.sqrt(np.mean(e[early] ** 2))), float(np.sqrt(np.mean(e[~early] ** 2)))
        rows.append({"record": name, "window_s": window, "start_rmse": a, "rest_rmse": b})
        if a > START_RATIO * b and a > 2.0 * noise_sd:
            flagged.append(f"{name} (first {window:.3g} s: RMSE {a:.4g} vs {b:.4g} after)")
    if not flagged:
        return rows, None
    if per_record:  # the fit gave each record its own start (`smafl_jax.identify._record_starts`) and still misses it
        return rows, (
            f"{START_MISMATCH} the joint model misses the start of {', '.join(flagged)}, although each record had its own "
            "thermal start and operator-memory rule: that record starts in a state those do not reach (an odd branch, a "
            "transient the lag cannot show). Fit it separately, or cut its first seconds"
        )
    return rows, (
        f"{START_MISMATCH} the joint model misses the start of {', '.join(flagged)}; one start rule serves every record, "
        "so a record that starts warm among records that start cold (or the reverse) is misfitted there and bends the "
        "thermal rate. Fit such records separately, or give records that start alike"
    )


def _outside(u, rng) -> float:
    u = np.asarray(u)
    return float(np.mean((u < rng[0]) | (u > rng[1])))


def _simulate_all(model, records):
    from ..models._simulate import simulate

    # each record from its own start (`for_record`: a joint fit may hold one thermal start per record)
    return [np.asarray(simulate(record_model(model, i), r.u, r.dt)) for i, r in enumerate(records)]


def _trained_hysteresis(model, records) -> dict:
    """fit.json ``data`` entries of a joint model's hysteresis input over all its records (each from its own start):
    the effective input range of a model with a thermal stage and the trained branches (`trained_branches_of`), so
    that `smafl simulate` / `control` check a new drive against them as for a one-record fit."""
    from ..models._range import EFFECTIVE_RULE, effective_range, hysteresis_values, trained_branches_of

    out: dict = {}
    eff = effective_range([(record_model(model, i), r.u, r.dt, None) for i, r in enumerate(records)])
    if eff is not None:
        out["effective_input_range"] = eff
        out["effective_input_range_rule"] = EFFECTIVE_RULE + "; over every record, each from its own fitted start"
    xs = [hysteresis_values(record_model(model, i), r.u, r.dt) for i, r in enumerate(records)]
    if all(x is not None and np.all(np.isfinite(x)) for x in xs):
        out["trained_branches"] = trained_branches_of([(x, None) for x in xs])
    return out


def _mean_metrics(rows: list[dict | None]) -> dict | None:
    ok = [r for r in rows if r]
    if not ok:
        return None
    out = {k: float(np.mean([r[k] for r in ok])) for k in ("rmse", "e_r_percent", "max_abs_error", "mean_abs_error")}
    out["n_samples"] = int(sum(r["n_samples"] for r in ok))
    out["n_folds"] = len(ok)
    return out


def loro_sentences(folds: list[dict]) -> list[str]:
    """One verdict per baseline over the LORO folds: per-record wins, median RMSE ratio, means of RMSE and e_r.

    The model "beats" a baseline only when its mean held-out RMSE is lower *and* it
    is lower on more than half of the held-out records: one badly predicted
    record (spikes, an odd run) must not decide the verdict either way.
    """
    out = []
    scored = [f for f in folds if f["model"]]
    if not scored:
        return ["no fold model gave a finite prediction: the model is not compared with the baselines"]
    n = len(scored)
    mm = _mean_metrics([f["model"] for f in scored])
    for k in BASELINES:
        bs = [f["baselines"][k] for f in scored]
        ratios = [f["model"]["rmse"] / b["rmse"] if b["rmse"] > 0 else math.inf for f, b in zip(scored, bs)]
        wins = sum(r < 1 for r in ratios)
        # e_r is the worst-case error a user meets: counted per record as well, so that a mean carried by one record
        # (a baseline's cubic blowing up on a sensor fault) does not read as a win on the others (new-user trial: "mean
        # e_r 76.5 % vs 211 %" with the model's e_r higher on 6 of 9 records)
        er_wins = sum(f["model"]["e_r_percent"] < b["e_r_percent"] for f, b in zip(scored, bs))
        mb = _mean_metrics(bs)
        nums = (
            f"lower held-out RMSE on {wins} of {n} records, median RMSE ratio {float(np.median(ratios)):.2f}, "
            f"lower e_r on {er_wins} of {n}; "
            f"mean RMSE {mm['rmse']:.4g} vs {mb['rmse']:.4g}, mean e_r {mm['e_r_percent']:.3g} % vs {mb['e_r_percent']:.3g} %"
        )
        if mm["rmse"] < mb["rmse"] and wins > n / 2:
            tie = "; by less than 5 % on the median record: practically a tie" if np.median(ratios) > TIE_RATIO else ""
            worse = f"; but its worst-case error e_r is higher on {n - er_wins} of {n} records" if er_wins <= n / 2 else ""
            out.append(f"the model beats baseline {k} in RMSE on held-out records: {nums}{tie}{worse}")
        else:
            out.append(f"the model does not beat baseline {k} ({BASELINE_TITLES[k]}) on held-out data: {nums}")
    return out


def fold_time_left(seconds: list[float], n_records: int) -> str:
    """``fold k/n took T; about L left``: the folds still to run and the joint fit on all records (a fold's fit on
    ``n_records / (n_records - 1)`` times the data).  The first fold compiles: from the second on, the later folds'
    median is the rate (a new-user trial's 9-record fit ran 7 min with nothing but "fold k/9" to go by)."""
    done = len(seconds)
    rate = float(np.median(seconds[1:])) if done > 1 else seconds[0]
    left = rate * (n_records - done) + rate * n_records / max(n_records - 1, 1)
    return (
        f"fold {done}/{n_records} took {format_seconds(seconds[-1])}; about {format_seconds(left)} left "
        f"({n_records - done} fold(s) and the joint fit on all records)"
    )


def _median_row(folds: list[dict]) -> str:
    """The LORO table's median row: one record cannot carry a median (the mean row above it can)."""

    def med(values):
        values = [x for x in values if x is not None and math.isfinite(x)]
        return float(np.median(values)) if values else None

    scored = [f for f in folds if f["model"]]
    ratios = [
        f["model"]["rmse"] / f["baselines"]["static_poly"]["rmse"] for f in scored if f["baselines"]["static_poly"]["rmse"] > 0
    ]
    cells = [med(f["model"][m] for f in scored) for m in ("rmse", "e_r_percent")]
    cells += [med(f["baselines"][k][m] for f in scored) for k in BASELINES for m in ("rmse", "e_r_percent")]
    return "| **median** | " + " | ".join(_fmt(c) for c in cells) + f" | {_fmt(med(ratios))} (of the records' ratios) |"


def _dominant_fold(folds: list[dict]) -> str | None:
    scored = [f for f in folds if f["model"]]
    if len(scored) < 3:
        return None
    r = np.array([f["model"]["rmse"] for f in scored])
    k = int(np.argmax(r))
    if r[k] > 0.5 * r.sum():
        return (
            f"the mean held-out error is dominated by record {scored[k]['record']} (RMSE {r[k]:.4g}; median over records "
            f"{float(np.median(r)):.4g}): look at its data-check findings before reading the mean"
        )
    return None


def _unique_names(records) -> list[str]:
    names = [r.name for r in records]
    seen = Counter(names)
    return [f"{n}#{i}" if seen[n] > 1 else n for i, n in enumerate(names)]


@blas_limited
def fit_records(
    records: Any, *, model: str = "auto", progress: bool = False, **fit_record_kwargs: Any
) -> tuple[Any, dict[str, Any], dict[str, Any]]:
    """Joint fit of one model to several records, with leave-one-record-out validation; ``(model, doc, details)``.

    ``records``: a list of `Record` with outputs (one column choice).  Options
    as for `fit_record` (``solver``, ``max_steps``, ``thresholds``, ``tilts``,
    ``grid``, ``orientation``, ``thermal_start``); ``split="auto"`` (default)
    validates by LORO when there are two or more records, ``split="none"``
    skips it (no held-out error, ``len(records)`` fewer refits).  ``doc`` is
    the fit.json content; ``details`` holds the per-record simulations for the
    figures (``yhat``: joint model, ``yhat_loro``: fold model with the record held out) and ``record_model``, the joint
    model as fitted (a cascade holds one thermal start and memory rule per record: run record i with
    ``record_model.for_record(i)``); the returned and saved model starts by the one shared rule, for new records.  ``model="auto"`` with
    leave-one-record-out on a directly measured input fits every registered hysteresis class and keeps the lowest
    mean held-out RMSE (`smafl_jax.report.choose_structure`; fit.json ``settings.structure_choice``).  ``hold_input``:
    as for `fit_record` (`smafl_jax.identify._hold`).
    """
    records = [records] if hasattr(records, "u") else list(records)
    hold = check_hold_input(fit_record_kwargs.get("hold_input", "auto"))
    fitted, doc, details = _fit_records(records, model, progress, fit_record_kwargs)
    return hold_fitted(fitted, doc, hold), doc, details


def _fit_records(records, model, progress, fit_record_kwargs):
    """`fit_records` before the saved model's input is held (`hold_fitted`)."""
    from ..report._report_fit import Candidate, choose_structure

    sparse = bool(fit_record_kwargs.pop("sparse_grid", False))
    if model != "auto" or len(records) < 2 or fit_record_kwargs.get("split", "auto") == "none":
        # nothing to compare classes on without leave-one-record-out: "auto" is then `auto_structure`'s class
        return _fit_records_structure(records, model=model, progress=progress, **fit_record_kwargs)
    # model auto: a directly measured input compares the hysteresis classes on the leave-one-record-out mean
    return choose_structure(
        records[0],
        lambda name, opts: Candidate.done(_fit_records_structure(records, model=name, progress=progress, **opts)),
        fit_record_kwargs,
        progress,
        validation="leave-one-record-out mean",
        sparse=sparse,
    )


def _fit_records_structure(
    records: Any, *, model: str = "auto", progress: bool = False, **fit_record_kwargs: Any
) -> tuple[Any, dict[str, Any], dict[str, Any]]:
    """`fit_records` of one structure (``model`` a name, or "auto" for the structure `auto_structure` names)."""
    from ..models._hysteresis import thermal_of
    from ..report._provenance import fit_header, solver_entry, versions
    from ..report._report_fit import K2_NOTE
    from ._fit import SOLVERS

    unknown = sorted(set(fit_record_kwargs) - set(FIT_OPTIONS))
    if unknown:
        raise UserInputError(f"fit_records: unknown option(s) {unknown}; known: {FIT_OPTIONS}")
    opts = {
        "split": "auto",
        "val_fraction": None,
        "solver": "lm",
        "max_steps": 300,
        "thresholds": None,
        "tilts": None,
        "grid": None,
        "orientation": "auto",
        "thermal_start": "auto",
        "sees": "auto",
        "gain_prior": GAIN_PRIOR,
        "hold_input": "auto",
    }
    opts.update(fit_record_kwargs)
    check_hold_input(opts["hold_input"])
    records = [records] if hasattr(records, "u") else list(records)
    if not records:
        raise UserInputError("no records to fit")
    for r in records:
        if r.y is None:
            raise UserInputError(f"{r.path or r.name}: no output column to fit")
    if opts["solver"] not in SOLVERS:
        raise UserInputError(f"unknown solver {opts['solver']!r}; choose one of {SOLVERS}")
    if opts["split"] not in ("auto", "none"):
        raise UserInputError(
            f"with several records the validation is leave-one-record-out (split 'auto') or none (split 'none'); "
            f"split {opts['split']!r} applies to one record"
        )
    loro = opts["split"] == "auto" and len(records) >= 2
    names = _unique_names(records)
    say = progress_line if progress else log.info
    keys = ("solver", "max_steps", "thresholds", "tilts", "grid", "orientation", "thermal_start", "sees", "gain_prior")
    fit_kw = {k: opts[k] for k in keys}
    squared = is_voltage(records[0].input_name, records[0].units)
    t_all = time.perf_counter()

    folds, yhat_loro, hold_check = [], [None] * len(records), None
    if loro:
        runs = []
        for i, rec in enumerate(records):
            train = [r for j, r in enumerate(records) if j != i]
            say(f"leave-one-record-out fold {i + 1}/{len(records)}: {names[i]} held out, {len(train)} records train")
            t0 = time.perf_counter()
            res_i, info_i = _joint_fit(train, model=model, progress=False, **fit_kw)
            # the fold model held as the saved one will be, to the range of its own training records, and as fitted
            held_i = hold_on(res_i.model, [(r, None) for r in train], opts["hold_input"])
            preds = {"held": _heldout(held_i, info_i, rec)}
            if held_i is not res_i.model:
                preds["extrapolating"] = _heldout(res_i.model, info_i, rec)
            runs.append((i, rec, train, res_i, info_i, preds, time.perf_counter() - t0))
        way, hold_check = _hold_by_folds(runs, opts["hold_input"])
        for i, rec, train, res_i, info_i, preds, seconds in runs:
            y_i, scored, start_i = preds.get(way, preds["held"])
            finite = bool(np.all(np.isfinite(y_i)))
            m_i = metrics(rec.y[scored], y_i[scored]) if finite else None
            yhat_loro[i] = y_i if finite else None
            bl = baselines_doc(train, [r.measured for r in train], [rec], [scored], squared=squared, model_heldout=m_i)
            folds.append(
                {
                    "record": names[i],
                    "structure": info_i["structure"],
                    "model": m_i,
                    "heldout_start": start_i,
                    "baselines": {k: bl["models"][k]["heldout"] for k in BASELINES},
                    "baseline_params": {k: bl["models"][k]["params"] for k in BASELINES},
                    "train_input_range": _input_range(train),
                    "heldout_input_range": _input_range([rec]),
                    "heldout_outside_train_range": _outside(rec.u, _input_range(train)),
                    "solver_message": res_i.message,
                    "seconds": seconds,
                    "note": None if finite else "the fold model gives non-finite output on this record",
                }
            )
            say(
                f"  held-out {names[i]}: "
                + (f"RMSE {m_i['rmse']:.4g}, e_r {m_i['e_r_percent']:.3g} %" if m_i else "non-finite output")
                + "; baselines "
                + ", ".join(f"{k} RMSE {v['rmse']:.4g}" for k, v in folds[-1]["baselines"].items())
            )
            say("  " + fold_time_left([f["seconds"] for f in folds], len(records)))

    say(f"joint fit on all {len(records)} records")
    t0 = time.perf_counter()
    res, info = _joint_fit(records, model=model, progress=progress, **fit_kw)
    seconds = time.perf_counter() - t0
    yhat = _simulate_all(res.model, records)
    fitted_starts = thermal_of(res.model).n_record_starts if thermal_of(res.model) is not None else None
    record_u0 = [float(v) for v in thermal_of(res.model).u0] if fitted_starts else None
    record_memory = (info["record_starts"] or {}).get("memory") if record_u0 else None  # the rules are not trained
    record_model = res.model
    res = res._replace(model=_with_shared_start(res.model, info))  # saved and returned: the shared start (a new record's)
    for r, y in zip(records, yhat):
        if not np.all(np.isfinite(y)):
            raise UserInputError(f"{r.path or r.name}: the joint model gives non-finite output ({res.message})")
    per_train = [metrics(r.y[r.measured], y[r.measured]) for r, y in zip(records, yhat)]
    pooled_train = metrics(
        np.concatenate([r.y[r.measured] for r in records]), np.concatenate([y[r.measured] for r, y in zip(records, yhat)])
    )

    # baselines of the final fit (all records train) and their LORO scores
    final_bl = baselines_doc(
        records,
        [r.measured for r in records],
        records,
        [np.zeros(len(r), bool) for r in records],
        squared=squared,
        model_heldout=None,
    )
    mean_model = _mean_metrics([f["model"] for f in folds]) if folds else None
    for k in BASELINES:
        final_bl["models"][k]["heldout"] = _mean_metrics([f["baselines"][k] for f in folds]) if folds else None
    final_bl["heldout_kind"] = (
        "mean over leave-one-record-out folds (each baseline refitted on the training records of the fold)" if folds else None
    )
    final_bl["verdict"] = (
        loro_sentences(folds) if folds else compare_sentences(None, {k: final_bl["models"][k]["heldout"] for k in BASELINES})
    )

    notes = list(info["notes"])
    if any(not r.measured.all() for r in records):
        notes.append(interpolated_note(records))
    if thermal_of(res.model) is not None:  # a thermal lag in front of a hysteresis: k2 cancels (a cascade)
        notes.append(K2_NOTE)
        if len(records) > 1 and record_u0:
            notes.append(
                "each record starts from its own fitted thermal state (the state a constant u0 V would hold: "
                + ", ".join(f"{n} {v:.4g}" for n, v in zip(names, record_u0))
                + "; per_record_start in fit.json); the saved model starts by the screened shared rule "
                f"({thermal_of(res.model).start_description()}): on a new record use the initial-state rule estimate "
                "(`smafl simulate --initial-state estimate`) when it may start otherwise; `smafl simulate` of a training "
                "record (the same file) runs it from its own start"
            )
        elif len(records) > 1:
            notes.append(
                "one thermal start rule is shared by all records (each record starts from it with its own first input); "
                "a fitted start temperature is not per record"
            )
    noise = noise_floor(list(records), train=pooled_train, validation=mean_model)
    if noise_floor_note(noise):
        notes.append(noise_floor_note(noise))
    starts = None
    if thermal_of(res.model) is not None and len(records) > 1:
        starts, start_note = start_mismatch(
            records, yhat, float(thermal_of(res.model).k1), float(noise["sd"]), names, per_record=bool(record_u0)
        )
        if start_note:
            notes.append(start_note)
        if record_u0:
            # every record (the start/rest errors only where the record is long enough for the window)
            by = {row["record"]: row for row in starts}
            rules = record_memory or [None] * len(names)
            starts = [{**by.get(n, {"record": n}), "u0_V": v, "memory": r} for n, v, r in zip(names, record_u0, rules)]
    if not res.converged:
        notes.append(f"solver: {res.message}")
    for f in folds:
        if f["heldout_outside_train_range"] > 0.01:
            lo, hi = f["train_input_range"]
            notes.append(
                f"held-out record {f['record']}: {100 * f['heldout_outside_train_range']:.1f} % of its input lies outside the "
                f"other records' range [{lo:.4g}, {hi:.4g}]; its held-out error there measures extrapolation"
            )
    if folds and any(f["model"] is None for f in folds):
        notes.append("some fold models gave non-finite output on their held-out record; the mean is over the other folds")
    if folds:
        structures = {f["structure"] for f in folds} | {info["structure"]}
        if len(structures) > 1:
            notes.append(f"model auto chose different structures across folds: {sorted(structures)}")
    heavy = _dominant_fold(folds)
    if heavy:
        notes.append(heavy)
    if len(records) == 1:
        notes.append("one record: no leave-one-record-out validation (give two or more records for a held-out error)")
    elif not loro:
        notes.append("leave-one-record-out validation skipped (split 'none'): no held-out error")

    dts = [float(r.dt) for r in records]
    doc = {
        **fit_header(res.model),
        "metrics": {
            "train": pooled_train,
            "validation": mean_model,
            "noise": noise,
        },
        "data": {
            "file": None,
            "files": [Path(r.path).name if r.path else None for r in records],
            "input_column": records[0].input_name,
            "output_column": records[0].output_name,
            "sample_time_s": float(np.median(dts)),
            "n_samples": int(sum(len(r) for r in records)),
            "n_records": len(records),
            "units": dict(records[0].units),
            "input_range": _input_range(records),
            "input_range_rule": "min and max of the input over all records (the joint model trains on every sample)",
            "output_range": value_range(np.concatenate([np.asarray(r.y, np.float64)[train_output_mask(r)] for r in records])),
            "output_range_rule": OUTPUT_RANGE_RULE,
            "records": [
                {
                    "name": n,
                    "path": str(r.path) if r.path else None,
                    "sha256": r.sha256,
                    "n_samples": len(r),
                    "sample_time_s": float(r.dt),
                    "input_range": _input_range([r]),
                    "processing": list(r.processing),
                    "load": r.load,
                }
                for n, r in zip(names, records)
            ],
        },
        "split": {
            "kind": "leave_one_record_out" if loro else "none",
            "rule": (
                f"leave one record out: {len(records)} folds, each refits on the other records and scores the held-out record "
                + (
                    "after its first window, from the start estimated on that window (thermal state x operator memory, "
                    "`estimate_initial_state`; validation.folds[].heldout_start)"
                    if any(f["heldout_start"]["rule"].startswith("estimated") for f in folds)
                    else "whole (simulated from its own first sample)"
                )
                + "; headline = mean over folds; the kept model is the joint fit on all records"
                if loro
                else "all records train; no held-out error"
            ),
        },
        "validation": {
            "kind": "leave_one_record_out" if loro else None,
            "folds": folds,
            "mean": {"model": mean_model, **{k: final_bl["models"][k]["heldout"] for k in BASELINES}} if folds else None,
        },
        "per_record_train": {n: m for n, m in zip(names, per_train)},
        "per_record_start": starts,
        "baselines": final_bl,
        "data_checks": data_checks_doc(records),
        "settings": {
            "model": model,
            "structure": info["structure"],
            "orientation": opts["orientation"],
            "thermal_start": opts["thermal_start"],
            "sees": opts["sees"],
            "start_screening": info["screening"],
            "split": "leave_one_record_out" if loro else "none",
            "solver": opts["solver"],
            "max_steps": opts["max_steps"],
            "train_thresholds": info["thresholds"],
            "train_tilts": info["tilts"],
            "gain_prior": opts["gain_prior"],
            "grid": opts["grid"] or {},
            "init": (res.info or {}).get("init"),
        },
        "solver": solver_entry(
            res,
            seconds,
            total_seconds_with_folds=time.perf_counter() - t_all,
            profile_k1=info["profile"].get("k1"),
            gain_prior=(res.info or {}).get("gain_prior"),
        ),
        "notes": notes,
        "versions": versions(),
    }
    doc["data"].update(_trained_hysteresis(record_model, records))
    # record_model: the joint fit as fitted, each training record from its own start (`record_model(model, i)`)
    details = {"names": names, "yhat": yhat, "yhat_loro": yhat_loro, "record_model": record_model}
    if hold_check is not None:
        doc["settings"]["hold_input_check"] = hold_check
    return res.model, doc, details


# -- outputs ----------------------------------------------------------------------------


def _fmt(x) -> str:
    return "n/a" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:.4g}"


def _report_md(doc: dict, files: dict) -> str:
    d, s, sv, v = doc["data"], doc["settings"], doc["solver"], doc["validation"]
    lines = [
        f"# Joint fit of {d['n_records']} records ({s['structure']})",
        "",
        f"- input `{d['input_column']}`, output `{d['output_column']}`, {d['n_samples']} samples in all; "
        f"training input range [{d['input_range'][0]:.6g}, {d['input_range'][1]:.6g}]",
        f"- validation: {doc['split']['rule']}",
        f"- final solver: {sv['name']} ({sv['n_steps']} steps, {sv['seconds']:.1f} s; {sv['total_seconds_with_folds']:.1f} s "
        f"with the folds): {sv['message']}",
        "",
        "## Records",
        "",
        "| record | samples | dt (s) | input range | joint-fit RMSE (in sample) | e_r (%) | fitted start | loading |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    starts = {row["record"]: row for row in doc.get("per_record_start") or [] if "u0_V" in row}
    for rec in d["records"]:
        m = doc["per_record_train"][rec["name"]]
        proc = "; ".join(rec["processing"]) or "as read"
        st = starts.get(rec["name"])
        start = f"{st['u0_V']:.3g} V" + (f", {st['memory']} memory" if st.get("memory") else "") if st else "shared rule"
        lines.append(
            f"| `{rec['name']}` | {rec['n_samples']} | {rec['sample_time_s']:.6g} | "
            f"[{rec['input_range'][0]:.4g}, {rec['input_range'][1]:.4g}] | {_fmt(m['rmse'])} | {_fmt(m['e_r_percent'])} | {start} "
            f"| {proc} |"
        )
    if v["folds"]:
        mean = v["mean"]
        lines += [
            "",
            "## Leave-one-record-out (held-out errors)",
            "",
            f"Headline: mean held-out RMSE **{_fmt(mean['model'] and mean['model']['rmse'])}**, mean e_r "
            f"**{_fmt(mean['model'] and mean['model']['e_r_percent'])} %** over {len(v['folds'])} folds "
            "(e_r per held-out record's output range)."
            + (
                f" Output noise SD {_fmt(doc['metrics']['noise']['sd'])} (estimated from the data): mean held-out RMSE = "
                f"{_fmt(doc['metrics']['noise']['validation_ratio'])}x, in-sample {_fmt(doc['metrics']['noise']['train_ratio'])}x."
                if (doc["metrics"].get("noise") or {}).get("sd")
                else ""
            ),
            "",
            "| held-out record | model RMSE | model e_r (%) | "
            + " | ".join(f"{k} RMSE | {k} e_r (%)" for k in BASELINES)
            + " | model / static_poly RMSE |",
            "| --- " * (4 + 2 * len(BASELINES)) + "|",
        ]
        for f in v["folds"]:
            m = f["model"] or {}
            ratio = m["rmse"] / f["baselines"]["static_poly"]["rmse"] if m and f["baselines"]["static_poly"]["rmse"] > 0 else None
            lines.append(
                f"| `{f['record']}` | {_fmt(m.get('rmse'))} | {_fmt(m.get('e_r_percent'))} | "
                + " | ".join(f"{_fmt(f['baselines'][k]['rmse'])} | {_fmt(f['baselines'][k]['e_r_percent'])}" for k in BASELINES)
                + f" | {_fmt(ratio)} |"
            )
        mm = mean["model"] or {}
        of_means = mm["rmse"] / mean["static_poly"]["rmse"] if mm and mean["static_poly"]["rmse"] > 0 else None
        lines.append(
            f"| **mean** | {_fmt(mm.get('rmse'))} | {_fmt(mm.get('e_r_percent'))} | "
            + " | ".join(f"{_fmt(mean[k]['rmse'])} | {_fmt(mean[k]['e_r_percent'])}" for k in BASELINES)
            + f" | {_fmt(of_means)} (of the means) |"
        )
        lines.append(_median_row(v["folds"]))
    lines += baselines_markdown(
        doc["baselines"], doc["metrics"]["validation"], doc["metrics"]["train"], heldout_label="LORO mean"
    )
    lines += data_checks_markdown(doc.get("data_checks"))
    lines += ["", "## Parameters", "", "- full parameters of the joint model: `fit.json`"]
    if doc["notes"]:
        lines += ["", "## Notes", ""] + [f"- {n}" for n in doc["notes"]]
    if files:
        lines += ["", "## Figures", ""]
        for key, title in [("records", "Measured, joint fit and leave-one-record-out prediction per record")]:
            if key in files:
                lines += [f"### {title}", "", f"![{title}]({files[key]})", ""]
    return "\n".join(lines) + "\n"


def _figure(out: Path, records, doc, details) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .._io import atomic_savefig

    n = len(records)
    fig, axes = plt.subplots(n, 1, figsize=(9, 1.9 * n + 0.6), squeeze=False)
    for ax, r, name, y, yl in zip(axes[:, 0], records, details["names"], details["yhat"], details["yhat_loro"]):
        ax.plot(r.time, r.y, lw=0.9, color="0.2", label="measured")
        ax.plot(r.time, y, lw=0.9, color="C1", label="joint fit")
        if yl is not None:
            ax.plot(r.time, yl, lw=0.9, color="C0", ls="--", label="held out (LORO)")
        ax.set_title(name, fontsize=8)
        ax.set_ylabel(_axis_label(r.output_name or "output", getattr(r, "units", None)), fontsize=7)
    axes[0, 0].legend(loc="best", fontsize=7)
    axes[-1, 0].set_xlabel("time (s)")
    fig.tight_layout()
    atomic_savefig(fig, out / "fit_records.png")
    plt.close(fig)
    return {"records": "fit_records.png"}


def write_records_outputs(out, records, doc, details, *, figures: bool = True) -> dict:
    """Write ``fit.json``, ``report.md`` and (``figures``) ``fit_records.png`` of a `fit_records` result into ``out``."""
    from .._io import atomic_write_json, atomic_write_text

    out = Path(out)
    files = _figure(out, records, doc, details) if figures else {}
    doc = dict(doc, figures=files)
    atomic_write_json(out / "fit.json", doc)
    atomic_write_text(out / "report.md", _report_md(doc, files))
    return doc
