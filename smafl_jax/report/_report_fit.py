"""Fitting one record end to end: model choice, split, fit, metrics, fit.json, report, figures.

Shared by ``smafl fit`` and ``experiments/fit_folder.py``.  Metrics are
computed on one simulation of the whole record (memory stays continuous) and
scored on the train and validation masks separately; e_r (eq. 3) divides by
the measured output range *of that subset*.
"""

from __future__ import annotations

import concurrent.futures
import contextvars
import dataclasses
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from .._blas import blas_limited
from .._errors import UserInputError
from .._io import atomic_savefig, atomic_write_json, atomic_write_text, model_from_dict, model_to_dict
from .._progress import current_tag, say, shown, tagged
from ..data.split import COVERAGE_WARN, branch_coverage
from ..identify._baselines import is_voltage
from ..identify._choose import (
    NEGATIVE_DRIVE_TOLERANCE,
    auto_candidates,
    auto_structure,
    candidate_model,
    drives_joule_heating,
    fitted_memory_start,
    negative_drive_excess,
    refine_thermal_start,
    screen_start,
    shared_screening,
)
from ..identify._decimate import fit_view
from ..identify._fit import SOLVERS, default_trainable, fit
from ..identify._gain_prior import GAIN_PRIOR, check_gain_prior
from ..identify._hold import check_hold_input, hold_choice, hold_fitted, hold_on
from ..identify._metrics import metrics, noise_floor, noise_floor_note
from ..identify._split import interpolated_note, split_masks
from ..identify._spread import sweep_spread
from ..models._cascade import Cascade
from ..models._eupi import EUPI
from ..models._hysteresis import hysteresis_class, hysteresis_of, thermal_of
from ..models._joule_lag import JouleLag
from ..models._range import EFFECTIVE_RULE, effective_range, effective_values, hysteresis_values, trained_branches
from ..models._simulate import simulate
from ..models._thermal import JouleThermal
from ._provenance import fit_header, record_data, solver_entry, versions

__all__ = ["MODELS", "build_model", "choose_structure", "fit_record", "write_fit_outputs", "versions"]

from .._choices import HYSTERESIS, MODELS, SLOW_MODES


class Candidate(NamedTuple):
    """One structure's split fit for `choose_structure`: the split ``model``, its ``metrics`` (``train``,
    ``validation``), the profiled thermal rate ``profile_k1`` (None without a lag), and ``finish()`` -> ``(model, doc,
    extra)``: the rest of the fit (for one record: the whole-record refit and fit.json), run only for the structure
    that is kept (on the benchmark record the losing class's refit took 8 s of 90)."""

    model: Any
    metrics: dict[str, Any]
    profile_k1: float | None
    finish: Callable[[], tuple[Any, dict[str, Any], Any]]
    #: fraction of the validation samples on branches of the candidate's hysteresis input that its training part visits
    #: (`branch_coverage`); None when not measured (no validation samples, several records)
    coverage: float | None = None
    #: the whole-record refit already running on a side thread (`_fit_structure`'s ``early_refit``), else None:
    #: `choose_structure` waits for it whether or not the candidate is kept (no fit goes on behind the caller's back)
    pending: concurrent.futures.Future | None = None

    @classmethod
    def done(cls, result: tuple[Any, dict[str, Any], Any]) -> Candidate:
        """A fit that is already finished (the multi-record fit: its joint fit is part of what is compared)."""
        model, doc, _ = result
        return cls(model, doc["metrics"], (doc.get("solver") or {}).get("profile_k1"), lambda: result)


K2_NOTE = (
    "k2 is not identified by a cascade fit: the hysteresis sees sqrt(theta k1/k2) and theta is "
    "proportional to k2, so the displacement does not depend on k2; it is held at its start value. "
    "Fit --model joule (the paper's eq. 7 lag) for a K2, which is a different quantity."
)


def build_model(kind, record, *, n_sym=8, n_alpha=4, n_asym=4, poly_order=3, u_ref="auto", slow_mode=False):
    """Untrained model of ``kind`` for the record's input range.

    ``u_ref="auto"``: 0 for voltage inputs (column name containing "volt",
    the paper's origin), else the input minimum (temperature, pressure...).
    ``slow_mode``: a cascade's thermal stage gets a slow thermal mode (`slow_thermal_start`); ignored without one.
    """
    u = record.u
    u_min, u_max = float(np.min(u)), float(np.max(u))
    if not u_max > u_min:
        raise UserInputError(f"input column '{record.input_name}' is constant ({u_min:g}); nothing to identify")
    grid = dict(n_sym=n_sym, n_alpha=n_alpha, n_asym=n_asym, poly_order=poly_order)
    if kind == "eupi":
        if u_ref == "auto":
            ref = None if is_voltage(record.input_name, record.units) else u_min
        else:
            ref = {"zero": None, "min": u_min}[u_ref]
        return EUPI.from_range(u_min, u_max, u_ref=ref, **grid)
    if (kind in ("cascade", "joule") or kind.startswith("cascade-")) and negative_drive_excess(u) > 0:
        raise UserInputError(
            f"--model {kind} needs a drive voltage >= 0 as input (Joule heating goes with U^2; readings down to "
            f"{NEGATIVE_DRIVE_TOLERANCE:.0%} of the maximum below 0 count as noise on an off drive); "
            f"'{record.input_name}' goes down to {u_min:g} with a maximum of {u_max:g}"
        )
    thermal = slow_thermal_start(record) if slow_mode else JouleThermal()
    if kind == "cascade":
        return Cascade.from_range(u_max, thermal=thermal, **grid)
    if kind.startswith("cascade-") and kind[len("cascade-") :] in HYSTERESIS:
        # another registered class behind the same thermal lag, on its own default grid over [0, u_max]
        return Cascade(thermal=thermal, hysteresis=hysteresis_class(kind[len("cascade-") :]).for_cascade(u_max))
    if kind == "joule":
        return JouleLag(thermal=JouleThermal(), offset=np.asarray(float(record.y[0])))
    if kind in HYSTERESIS:  # any other registered hysteresis model (smafl_jax.models._hysteresis), on its default grid
        return hysteresis_class(kind).from_range(u_min, u_max)
    raise UserInputError(f"unknown model {kind!r}; choose one of {MODELS}")


#: Start of a slow thermal mode's fit (`slow_thermal_start`): time constant (s) and the share of the heat through it.
SLOW_START_TAU = 120.0
SLOW_START_SHARE = 0.25


def slow_thermal_start(record) -> JouleThermal:
    """The thermal stage a fit with a slow thermal mode starts from: the paper's rates, the slow mode at
    `SLOW_START_TAU` (at most a quarter of the record) carrying `SLOW_START_SHARE` of the heat; the fit trains both.

    Why these: on the independent plant D (a wire in a 20-150 s sleeve), a grid of fixed slow modes over the default fit
    put the lowest validation error at 120 s and 25 % (experiments/plant_d_thermal_mass.py)."""
    tau = min(SLOW_START_TAU, 0.25 * len(record) * float(record.dt))
    return JouleThermal().with_slow_mode(1.0 / tau, SLOW_START_SHARE / (1.0 - SLOW_START_SHARE))


#: Share of the heat through the slow mode added to a one-mode fit (`slow_warm_start`).
SLOW_WARM_SHARE = 0.05


def slow_warm_start(model, record, weights):
    """A one-mode fit ``model`` with a small slow thermal mode added (`SLOW_START_TAU` at most a quarter of the record,
    `SLOW_WARM_SHARE` of the heat), its thermal rate, start and slow mode searched with the gains profiled
    (`refine_thermal_start` on the samples ``weights`` selects); the fit trains them all after.

    Why: started from `slow_thermal_start` and screened afresh, a class's fit with a slow mode ended worse on the
    validation block than the same class's fit without one, though it nests it (independent plant D, a 20 s sleeve:
    0.083-0.51 against 0.036; a 54 % sleeve: 1.75 against 1.53).  From the class's own one-mode optimum, the search can
    only lower the training loss, and what the slow mode adds is what is left to explain."""
    th = thermal_of(model)
    if th.init != "given":  # the search runs in a given start (`refine_thermal_start`): the state the rule gives
        u_first = float(np.asarray(record.u)[0])
        model = model.with_thermal_start("given", 0.0 if th.init == "ambient" else u_first)
    tau = min(SLOW_START_TAU, 0.25 * len(record) * float(record.dt))
    slow = model.thermal.with_slow_mode(1.0 / tau, SLOW_WARM_SHARE / (1.0 - SLOW_WARM_SHARE))
    model = dataclasses.replace(model, thermal=slow)
    _, got, _ = refine_thermal_start(model, record, weights, float(np.max(np.asarray(record.u))))
    return got


#: Start of the note (printed as a warning by `smafl fit`) for a static hysteresis class fitted to a drive voltage.
STATIC_ON_DRIVE = "static model on a drive voltage:"
#: Start of the note (printed as a warning by `smafl fit`) when two equally good fits part on sweeps of the trained range.
BRANCHES_OPEN = "branches the record leaves open:"


def structure_start(model, record, thresholds, tilts, grid, slow_mode=False):
    """``(structure, thresholds, tilts, untrained start, notes)``: the model choice shared by `fit_record` and the
    multi-record fit (``model="auto"`` picks the structure from the input and trains thresholds and tilts;
    ``slow_mode``: a cascade with a slow thermal mode, `build_model`)."""
    notes = []
    structure = model
    if model == "auto":
        structure, why = auto_structure(record)
        notes.append(f"model auto -> {structure}: {why}")
    start = build_model(structure, record, **(grid or {}), slow_mode=slow_mode)
    if thermal_of(start) is None and drives_joule_heating(record):
        # measured on an independent plant's PWM record: a static Preisach of the voltage left 250x the noise held out
        notes.append(
            f"{STATIC_ON_DRIVE} '{record.input_name}' is a drive voltage, but --model {model} fits a static hysteresis of "
            "it with no thermal lag between the drive and the actuator; --model auto fits the Joule-heating cascade"
        )
    thresholds = (model == "auto") if thresholds is None else bool(thresholds)
    tilts = (model == "auto") if tilts is None else bool(tilts)
    return structure, thresholds, tilts, start, notes


def joint_steps(start, max_steps, notes):
    """``max_steps`` of the joint refinement for this start: 0 (with a note) for a hysteresis class that declares the
    profiled start its fit (`AbstractHysteresis.refine_jointly`)."""
    h = hysteresis_of(start)
    if h is None or h.refine_jointly or max_steps == 0:
        return max_steps
    notes.append(
        f"no joint refinement: {type(h).__name__}'s weights are solved exactly (bounded least squares) at the profiled "
        "start, which is the fit"
    )
    return 0


@blas_limited
def fit_record(record, *, model="auto", progress=False, **options):
    """Fit one record; returns ``(fitted_model, doc, masks)`` with ``doc`` the fit.json content.

    ``model="auto"`` picks the structure from the input (`auto_candidates`) and trains the play
    thresholds and tilts too (``thresholds`` / ``tilts`` None = on for auto, off otherwise).  A directly
    measured input gets every registered hysteresis class fitted, and the lowest validation RMSE chooses
    (fit.json ``settings.structure_choice``, with each candidate's RMSE and e_r); a drive voltage gets every class behind
    the Joule thermal lag (the cascades), compared the same way, except that the paper's EUPI cascade is kept over a class
    that beats it on validation by less than `DEFAULT_CLASS_MARGIN` while fitting the training samples no better.
    For every structure with a hysteresis part the output orientation and, for a cascade, the thermal start state
    are screened on the training samples (`smafl_jax.identify.screen_start`) before the joint refinement.

    Options, each the ``smafl fit`` flag of the same name with the same default (``smafl fit --help``): ``split``
    ("auto", "branch", "time", "none"), ``val_fraction`` (0.3), ``solver`` ("lm", one of `smafl_jax.SOLVERS`),
    ``max_steps`` (300), ``thresholds`` / ``tilts`` (None), ``grid`` (dict of ``n_sym``, ``n_alpha``, ``n_asym``,
    ``poly_order``), ``orientation``, ``thermal_start``, ``sees``, ``memory`` (all "auto"), ``refit`` (True; the
    flag is ``--no-refit``), ``gain_prior`` (1.0, None for plain least squares), ``early_stopping``, ``median`` and
    ``sparse_grid`` (False), ``hold_input`` ("auto": the saved model's hysteresis holds a directly measured input to its
    trained range, a cascade's thermal state to its low edge, `smafl_jax.identify._hold`).  ``progress``: progress lines on the ``smafl_jax`` progress logger.  Lower level: `smafl_jax.fit` trains
    a model as given, without the screening or the split.
    """
    if record.y is None:
        raise UserInputError(f"{record.path}: no output column to fit")
    hold = check_hold_input(options.get("hold_input", "auto"))
    fitted, doc, masks = _fit_record(record, model, progress, options)
    return hold_fitted(fitted, doc, hold), doc, masks


def _fit_record(record, model, progress, options):
    """`fit_record` before the saved model's input is held (`hold_fitted`)."""
    median = bool(options.pop("median", False))
    sparse = bool(options.pop("sparse_grid", False))
    slow = options.pop("slow_mode", "auto")
    if slow not in SLOW_MODES:
        raise UserInputError(f"unknown slow_mode {slow!r}; choose one of {SLOW_MODES}")
    if median and (model != "auto" or options.get("split") == "none"):
        raise UserInputError(
            "median combines the classes --model auto compares on a validation split: use model auto, split not none"
        )
    if model != "auto" or options.get("split") == "none":  # split none: no validation error to compare classes on
        return _fit_structure(record, model=model, progress=progress, slow_mode=slow == "on", **options)
    return choose_structure(
        record,
        # the other hysteresis input only for the default class ("auto"): it doubles a class's refinements, and on the
        # Preisach classes it changed 2 of 39 random plant-A cells, both for the worse (session 49: s233 1.10x -> 1.55x,
        # s237 1.42x -> 2.59x through the class choice)
        lambda name, opts: _fit_structure(
            record,
            model=name,
            progress=progress,
            defer_refit=True,
            other_inputs=name == "auto",
            early_refit=name == "auto",
            **opts,
        ),
        {**options, **({"slow_mode": True} if slow == "on" else {})},
        progress,
        median=median,
        sparse=sparse,
        slow_check=slow == "auto",
    )


def _median_doc(record, runs, kept, final, doc, extra, progress, refitted=None):
    """fit.json ``median``: the sample-by-sample median of every compared class (`MedianOfModels`), each class refitted
    on the whole record, with the median of the split models scored on the same training / validation samples.
    ``kept``: the index of the kept run (refitted as ``final``); ``refitted``: {run index: model} refitted already.

    Why: on 60 independent records the median of the three classes held out 0.88x the geometric-mean error of the
    class the validation block keeps (experiments/results/random_levels_20min_session28.md; worse on issue 18's matrix).
    """
    from ..models._median import MedianOfModels

    train, val, _ = extra
    refitted = {**(refitted or {}), kept: final}  # `finish()` runs once per candidate
    finals = []
    for i, (name, c, _) in enumerate(runs):
        if i not in refitted:
            say(f"median: refitting {name} on the whole record", progress)
        finals.append(refitted[i] if i in refitted else c.finish()[0])
    split_y = np.median(np.stack([np.asarray(simulate(c.model, record.u, record.dt)) for _, c, _ in runs]), axis=0)
    median = MedianOfModels(tuple(finals))
    y_all = np.asarray(simulate(median, record.u, record.dt))
    mets = {
        "train": metrics(record.y[train], split_y[train]),
        "validation": metrics(record.y[val], split_y[val]) if val.any() else None,
        "whole_record": _whole_record(record, y_all),
    }
    mets["noise"] = noise_floor([record], **mets)
    return {
        **fit_header(median),
        "members": [name for name, _, _ in runs],
        "metrics": mets,
        # the raw input range only: each member has its own hysteresis input (thermal state), so no effective range
        "data": {k: v for k, v in doc["data"].items() if not k.startswith(("effective_input_range", "trained_branches"))},
        "notes": [
            "sample-by-sample median of the classes --model auto compared, each refitted on the whole record (fit.json "
            "holds the class the validation block kept); validation metrics are those of the median of the split models"
        ],
    }


# A thermal lag whose time constant spans at most this many samples is barely resolved by the record: `choose_structure`
# then compares the static hysteresis classes of the drive too.  Measured on the SMA wing reversal curves (10 s per
# sample): the cascade's fitted time constant moved between 0.9 and 5.3 samples with the EUPI start grid alone, and the
# static Preisach (validation RMSE 0.127) beat every cascade (0.25-0.91); a one-sample gate dropped it on one grid.
QUASI_STATIC_SAMPLES = 10.0


@blas_limited
def choose_structure(record, fit_one, options, progress, validation="validation", median=False, sparse=False, slow_check=False):
    """``--model auto``: fit every structure of `auto_candidates` with ``fit_one(name, options) -> Candidate`` and keep
    the lowest validation RMSE (``Candidate.metrics["validation"]``; on a drive voltage the default cascade when
    `_prefers_default`; ``sparse``: the default EUPI on its sparse grid
    too, `auto_candidates`); returns the winner's ``finish()``, ``(model, doc,
    extra)``, with ``settings.structure_choice`` (each candidate's validation RMSE and e_r, train RMSE, validation
    coverage, seconds) and a first note.  Only the winner is finished (for one record: refitted on the whole record).
    When every candidate's validation coverage (samples on branches its training part visits) is below `COVERAGE_WARN`,
    the choice is flagged ``extrapolating`` and the note says it is uncertain.

    Shared by the one-record fit (``validation``: the split's validation samples) and the multi-record fit (the
    leave-one-record-out mean).  A drive voltage: the default cascade is fitted first as ``"auto"``, then every other
    class behind the same lag (``cascade-preisach``); when the lag settles within `QUASI_STATIC_SAMPLES` samples
    (`JouleThermal.settles_within`: a record that barely shows the lag) the static hysteresis classes of the drive are fitted and compared too.  No validation error:
    the first candidate is kept.

    The candidates are fitted at once on `candidate_threads` threads (one per core, fit.json
    ``settings.structure_choice.threads``), with the results of fitting them one after another: each fit is
    deterministic and independent of the others, and the screening two classes share is made once
    (`shared_screening`).  Measured on the benchmark record (2 cores, quiet): 135.8 s one after another, 89.8 s on 2
    threads (the session-23 code 139.8 s).  Each candidate's ``seconds`` is its own wall time, which overlaps the others'.
    """
    candidates, why = auto_candidates(record, options.get("grid"), sparse)
    drive = candidates[0] not in HYSTERESIS  # a drive voltage: the default cascade first, as `fit_one("auto")` fits it
    candidates, left_out = _honouring_memory(candidates, record, options)
    why += left_out
    more = dict(options)
    for k in ("thresholds", "tilts"):  # auto's defaults for the other classes: trained (a class without them ignores them)
        more[k] = True if more.get(k) is None else more[k]

    def how_to_fit(i, name):
        """``(fit_one's model, its options)`` for candidate ``i``."""
        if drive and i == 0:
            return "auto", options
        # a class by name, or the default class on its sparse grid (the user's polynomial order kept)
        model, extra = candidate_model(name)
        grid = {**(more.get("grid") or {}), **extra.get("grid", {})}
        return model, {**more, **({"grid": grid} if grid else {})}

    def job(i, name):
        with tagged(name):
            t0 = time.perf_counter()
            got = fit_one(*how_to_fit(i, name))
            sec = time.perf_counter() - t0
        say(f"model auto: {name} fitted in {sec:.0f} s", progress)
        return got, sec

    threads = candidate_threads(len(candidates))
    say(
        f"model auto: fitting {len(candidates)} candidates ({', '.join(candidates)})"
        + (f", {threads} at a time; each line starts with its candidate" if threads > 1 else ""),
        progress,
    )
    # classes that screen on the same grid (Preisach and Gaussian Preisach) screen once (`shared_screening`); each
    # candidate runs in a copy of this context, so they share it, and one waits for a screening another is making
    with shown(progress), shared_screening(), _Pool(threads) as pool:
        futures = _submit_longest_first(pool, job, candidates)
        if drive:
            first, _ = futures[0].result()
            th = thermal_of(first.model)
            # the profiled k1 (gains solved at each rate) or the refined one: the refinement can trade a lag for hysteresis
            # memory on a record that has no lag to show (measured: SMA wing, profiled k1 1.08 1/s, refined slower)
            k_prof = first.profile_k1
            rates = [] if th is None else [float(th.k1), *([float(k_prof)] if k_prof else [])]
            fast = [k for k in rates if th.settles_within(record.dt, k, QUASI_STATIC_SAMPLES)]
            if fast:
                # a thermal lag within a few samples: the record barely shows it, and the static hysteresis classes of the
                # drive are compared too (measured: the SMA wing reversal curves at 10 s per sample, cascade validation RMSE
                # 0.66-0.91; a static Preisach of the voltage 0.127)
                why += (
                    f"; its thermal time constant ({1.0 / fast[0]:.3g} s) is within {QUASI_STATIC_SAMPLES:g} samples "
                    f"({QUASI_STATIC_SAMPLES * float(record.dt):.3g} s), so the record barely shows the lag: the static "
                    "hysteresis classes of the drive were fitted too and the held-out error chooses"
                )
                static, more_left = _honouring_memory(tuple(HYSTERESIS), record, options, keep_first=False)
                why, left_out = why + more_left, left_out + more_left
                futures += _submit_longest_first(pool, job, static, first=len(candidates))
                candidates = (*candidates, *static)
        early = _finish_best_when_idle(pool, threads, futures, candidates, progress, candidates[0] if drive else None)
        runs = [(name, *f.result()) for name, f in zip(candidates, futures)]
        early = {i: f.result() for i, f in early.items()}  # inside the block: a refit started early ends before it is left
        concurrent.futures.wait([c.pending for _, c, _ in runs if c.pending is not None])
    if len(runs) == 1:
        final, doc, extra = runs[0][1].finish()
        if left_out:  # the classes a named memory rule left out: said even when one class is left to fit
            doc["notes"] = [*doc.get("notes", []), f"model auto: {left_out[2:]}"]
        return final, doc, extra
    scored = [r for r in runs if r[1].metrics["validation"] is not None]
    if not scored:  # no validation error (split none): nothing to compare on; the first (default) class is kept
        name, kept, _ = runs[0]
        how = f"no {validation} error to compare on: the first candidate is kept"
    else:
        name, kept, _ = _best(scored, prefer=runs[0][0] if drive else None)
        how = _choice_reason(scored, name, runs[0][0] if drive else None, validation)
    covered = [c.coverage for _, c, _ in scored]
    uncertain = bool(covered) and all(v is not None and v < COVERAGE_WARN for v in covered)
    if uncertain:
        # Every class was judged on samples the training part never visited on their branch: the ranking measures
        # extrapolation.  Measured (independent random multi-level record, seed 21): the inner validation block was the
        # first cooling after a long hold; the kept Gaussian Preisach held out 11.4x the noise on new data where the
        # default EUPI cascade held out 1.4x.
        how += (
            f"; uncertain: the candidates were compared on validation samples of which only {100 * min(covered):.0f}-"
            f"{100 * max(covered):.0f} % lie on branches their training part visits, so every validation error is an "
            "extrapolation" + (f" (--model {runs[0][0]} fits the default class)" if name != runs[0][0] else "")
        )
    if len(runs) > 1:
        say(f"model auto: {name} kept ({how})", progress)
    k = next(i for i, r in enumerate(runs) if r[1] is kept)
    if k in early:  # refitted on a thread that went idle while the last candidates ran (`_finish_best_when_idle`)
        (final, doc, extra), fin_sec = early[k]
    else:
        t0 = time.perf_counter()
        final, doc, extra = kept.finish()
        fin_sec = time.perf_counter() - t0
    check, refits = None, {}
    # one record on a drive voltage (the classes compared behind one lag; measured there only): the kept class's
    # whole-record refit must fit that record
    if validation == "validation" and drive and scored:
        got, check, refits = _whole_record_check(runs, k, (final, doc, extra), early, progress)
        if got is not None:
            refits[k] = final  # the class it replaces, refitted already (`--median` takes every refit)
            (final, doc, extra), k, more_sec = got
            name, kept = runs[k][0], runs[k][1]
            fin_sec += more_sec
        if check and check["switched"]:
            how = f"{check['note']}; the validation block had chosen {check['validation_choice']} ({how})"
        elif check:
            how += "; " + check["note"]
    slow = None
    if slow_check and validation == "validation" and drive and scored:

        def fit_slow(i, warm):
            model_i, opts_i = how_to_fit(i, runs[i][0])
            return fit_one(model_i, {**opts_i, "slow_mode": True, **({"warm_start": runs[i][1].model} if warm else {})})

        got, slow = _slow_mode_check(runs, k, (final, doc, extra), fit_slow, progress)
        if got is not None:
            (final, doc, extra), more_sec = got
            fin_sec += more_sec
            name = f"{slow['class']} + slow thermal mode"
        if slow:
            how += "; " + slow["note"]
    table = [
        {
            "structure": n,
            "validation": c.metrics["validation"] and {k: c.metrics["validation"][k] for k in ("rmse", "e_r_percent")},
            "train_rmse": c.metrics["train"]["rmse"],
            "validation_coverage": c.coverage,
            "seconds": sec + (fin_sec if c is kept else 0.0),
        }
        for n, c, sec in runs
    ]
    choice = {
        "candidates": table,
        "chosen": name,
        "on": how,
        "threads": threads,
        **({"extrapolating": True} if uncertain else {}),
        **({"whole_record_check": check} if check else {}),
        **({"slow_mode_check": slow} if slow else {}),
    }
    doc["settings"] = {**doc["settings"], "model": "auto", "structure_choice": choice}
    if median and len(runs) > 1:
        refitted = {**{i: r[0][0] for i, r in early.items()}, **refits}
        doc["median"] = _median_doc(record, runs, k, final, doc, extra, progress, refitted)
    doc["notes"] = [
        f"model auto -> {name}: {why}; "
        + ", ".join(
            f"{t['structure']} {validation} RMSE {t['validation']['rmse']:.4g} (e_r {t['validation']['e_r_percent']:.3g} %)"
            if t["validation"]
            else f"{t['structure']} (no {validation} error)"
            for t in table
        )
        + f" -> {name} ({how}; only the kept structure is refitted on the whole record)",
        # the cascade fitted as "auto" said it too; a static class chosen here on held-out error is no user's mistake
        *(n for n in doc["notes"] if not n.startswith(("model auto -> ", STATIC_ON_DRIVE))),
    ]
    return final, doc, extra


#: `_whole_record_check`: a kept class whose whole-record refit leaves more than this many output noise SDs (RMSE over the
#: noise SD estimated from the data) on the record it was fitted on has the other compared classes refitted too ...
WHOLE_RECORD_CHECK = 2.0
#: ... and one of them replaces it when its whole-record RMSE is lower by more than this factor.
WHOLE_RECORD_MARGIN = 2.0


def _left_on_record(doc, what, doing, progress) -> float | None:
    """The kept fit's whole-record RMSE over the noise SD (fit.json ``metrics.noise.whole_record_ratio``) when it is
    above `WHOLE_RECORD_CHECK` (said as a progress line: ``what`` leaves it, so ``doing``), else None: the fit leaves
    structure on the very record it was fitted on."""
    ratio = ((doc.get("metrics") or {}).get("noise") or {}).get("whole_record_ratio")
    if ratio is None or not np.isfinite(ratio) or ratio <= WHOLE_RECORD_CHECK:
        return None
    say(f"model auto: the kept {what} leaves {ratio:.3g}x the output noise SD on its record; {doing}", progress)
    return ratio


def _whole_rmse(doc) -> float:
    """Whole-record RMSE of a finished fit's fit.json; inf for a refit without finite output (it cannot win)."""
    m = (doc.get("metrics") or {}).get("whole_record")
    return _rmse_or_inf(m) if m else np.inf


def _whole_record_check(runs, k, done, early, progress):
    """``(None or ((model, doc, extra), index, seconds), info or None, {index: model})``: the kept run ``k``'s
    whole-record refit ``done`` checked against the record, and replaced by another class's when that one fits the whole
    record far better; the last item holds the models of the other classes refitted for the check.

    Why: the class is chosen on the validation block, which is often an extrapolation (branches the training part never
    walked); the whole-record refit then shows whether the kept class can fit the record at all.  Measured on an
    independent plant with rescaled-branch (Liang-Rogers) kinetics and a step drive (experiments/indep_plant_d.py, seed
    1, steps 5 Hz): the EUPI cascade won a validation block at 56 % coverage (300x the noise, the others 370x) and its
    whole-record refit stayed at 32x the noise, where the phase cascade's reached 4.3x; held out 62x -> 15.6x.  On
    the stored per-class fits of 120 independent records (sessions 27-28 and 54; each class's saved model is its
    whole-record refit) this rule changed 5 choices, each better held out (62.4 -> 9.2, 2.7 -> 2.3, 71 -> 15, 425 -> 251,
    151 -> 94x the noise) and none worse.  The refits of the other classes cost time only when the check fires."""
    final, doc, extra = done
    kept_name = runs[k][0]
    ratio = _left_on_record(doc, f"{kept_name}'s whole-record refit", "refitting the other classes on the whole record", progress)
    if ratio is None:
        return None, None, {}
    rmse = _whole_rmse
    t0 = time.perf_counter()
    todo = [i for i, (_, cand, _) in enumerate(runs) if i != k and i not in early and cand.metrics.get("validation") is not None]

    def refit(i):
        with tagged(runs[i][0]):
            return runs[i][1].finish()

    with _Pool(candidate_threads(len(todo))) as pool:  # one refit per core, as the candidates were fitted
        futures = {i: pool.submit(refit, i) for i in todo}
        refits = {i: f.result() for i, f in futures.items()}
    refits.update({i: early[i][0] for i in early if i != k})
    scores = {kept_name: rmse(doc), **{runs[i][0]: rmse(r[1]) for i, r in refits.items()}}
    best = min(refits, key=lambda i: rmse(refits[i][1]), default=None)
    switch = best is not None and rmse(refits[best][1]) * WHOLE_RECORD_MARGIN < rmse(doc)
    shown = ", ".join(f"{n} {v:.4g}" for n, v in scores.items())
    note = (
        f"whole-record check: {kept_name} refitted on the whole record "
        f"left {ratio:.3g}x the noise SD; whole-record RMSE {shown}"
        + (
            f" -> {runs[best][0]} (lower by more than {WHOLE_RECORD_MARGIN:g}x: a class that cannot fit the record it was "
            "chosen on is not kept)"
            if switch
            else f" -> {kept_name} kept (no class lower by more than {WHOLE_RECORD_MARGIN:g}x)"
        )
    )
    info = {
        "whole_record_rmse": {n: (v if np.isfinite(v) else None) for n, v in scores.items()},  # JSON has no inf
        "noise_ratio": ratio,
        "validation_choice": kept_name,
        "switched": bool(switch),
        "note": note,
    }
    say(f"model auto: {note}", progress)
    models = {i: r[0] for i, r in refits.items()}
    if not switch:
        return None, info, models
    return (refits[best], best, time.perf_counter() - t0), info, models


#: `_slow_mode_check`: the class with a slow thermal mode replaces the kept fit when its validation RMSE is lower by more
#: than this factor (and its whole-record RMSE is lower too).
SLOW_MODE_MARGIN = 1.2


def _slow_mode_check(runs, k, done, fit_slow, progress):
    """``(None or ((model, doc, extra), seconds), info or None)``: when the kept fit ``done`` (run ``k``) leaves more than
    `WHOLE_RECORD_CHECK` noise SDs on its own record, every compared class is fitted again with a slow thermal mode
    twice (``fit_slow(i, warm)`` -> `Candidate`, one per core): from a fresh screening (`slow_thermal_start`) and from
    the class's own one-mode split fit (``warm``, `slow_warm_start`), the start lower on the validation block kept; the
    class lowest there replaces the kept fit when it is lower than the kept fit by more than `SLOW_MODE_MARGIN` and lower
    on the whole record too.

    Why both starts (independent plant D, sleeve only, 9 records): the fresh start alone missed a 20 s sleeve and ended
    worse on validation than the class without the mode; from the one-mode fit alone the held-out error rose on 3 records
    (26x -> 272x, 4.7x -> 9.9x, 33x -> 280x the noise) and fell on 2 (13.8x -> 9.1x, 184x -> 90x).  A fit whose slow
    mode ended faster than the wire does not count (`refine_thermal_start` keeps the search below the wire's rate).

    Why: a wire wound on a nylon line, in a sleeve or on clamps warms a second, slower mass; one thermal lag then leaves
    a slow drift that no hysteresis class absorbs (independent plant D, a 20-150 s sleeve: default fits 9-99x the noise
    where the same plant without the sleeve fits at 4-6x).  Every class, not the kept one alone: the class that wins
    with one lag need not be the one that fits with two (plant D seed 1, triangle: the EUPI cascade was kept, and with
    a slow mode it still left 63x the noise on its record).  Only when the kept fit is far from the noise: the extra
    fits cost what the class comparison cost, and a record at the noise floor has no slow mode to show."""
    final, doc, extra = done
    kept_name = runs[k][0]
    if thermal_of(final) is None:
        return None, None
    ratio = _left_on_record(doc, kept_name, "fitting the classes again with a slow thermal mode", progress)
    if ratio is None:
        return None, None
    t0 = time.perf_counter()
    todo = [i for i, (_, c, _) in enumerate(runs) if c.metrics.get("validation") is not None and thermal_of(c.model) is not None]

    def job(i, warm):
        with tagged(f"{runs[i][0]} + slow" + (" from its one-mode fit" if warm else "")):
            return fit_slow(i, warm)

    # the fresh fits (a screening each) first: the longest first on the threads
    jobs = [(i, warm) for warm in (False, True) for i in todo]
    with _Pool(candidate_threads(len(jobs))) as pool:
        futures = {key: pool.submit(job, *key) for key in jobs}
        both = {key: f.result() for key, f in futures.items()}
        concurrent.futures.wait([c.pending for c in both.values() if c.pending is not None])

    def val(c):
        th = thermal_of(c.model)
        if th is not None and th.has_slow_mode and not float(th.slow_k1) < float(th.k1):
            return np.inf  # the joint refinement made the slow mode faster than the wire: not a slower mass (see there)
        return _rmse_or_inf(c.metrics["validation"]) if c.metrics.get("validation") else np.inf

    # each class's start that is lower on the validation block (the fresh one on a tie)
    cands = {i: min((both[i, False], both[i, True]), key=val) for i in todo}

    whole = _whole_rmse

    def finite(v):  # JSON has no inf
        return v if v is not None and np.isfinite(v) else None

    best = min(cands, key=lambda i: val(cands[i]))
    v0, v1, w0, w1 = val(runs[k][1]), val(cands[best]), whole(doc), None
    got = None
    if v1 * SLOW_MODE_MARGIN < v0:
        got = cands[best].finish()
        w1 = whole(got[1])
        if not w1 < w0:
            got = None
    th = thermal_of(got[0]) if got is not None else thermal_of(cands[best].model)
    if got is not None:
        verdict = "kept"
    elif w1 is None:
        verdict = f"not kept (validation not lower by more than {SLOW_MODE_MARGIN:g}x)"
    else:
        verdict = "not kept (whole record not lower)"
    shown = ", ".join(f"{runs[i][0]} {val(c):.4g}" for i, c in cands.items())
    note = (
        f"slow thermal mode: {kept_name} left {ratio:.3g}x the noise SD on its record; with a slow mode, validation RMSE "
        f"{shown} (each the better of a fresh start and the class's one-mode fit); best {runs[best][0]}"
        f"{' from its one-mode fit' if cands[best] is both[best, True] else ''} (time constant {1 / float(th.slow_k1):.3g} s, "
        f"{100 * float(th.slow_ratio) / (1 + float(th.slow_ratio)):.3g} % of the heat): validation {v0:.4g} -> {v1:.4g}"
        + (f", whole record {w0:.4g} -> {w1:.4g}" if w1 is not None else "")
        + f": {verdict}"
    )
    say(f"model auto: {note}", progress)
    info = {
        "noise_ratio": ratio,
        "validation_rmse": {"without": finite(v0), **{runs[i][0]: finite(val(c)) for i, c in cands.items()}},
        "whole_record_rmse": {"without": finite(w0), "with": finite(w1)},
        # each class's validation RMSE from a fresh start and from its one-mode fit (`slow_warm_start`)
        "starts": {runs[i][0]: {"fresh": finite(val(both[i, False])), "one_mode_fit": finite(val(both[i, True]))} for i in todo},
        "class": runs[best][0],
        "slow_k1": float(th.slow_k1),
        "slow_share": float(th.slow_ratio) / (1.0 + float(th.slow_ratio)),
        "kept": got is not None,
        "note": note,
    }
    return (None if got is None else (got, time.perf_counter() - t0)), info


def _honouring_memory(candidates, record, options, keep_first=True):
    """``(candidates, reason)``: the `auto_candidates` labels whose hysteresis class has the operator-memory rule the user
    named (``options["memory"]``, e.g. ``from_top``, a rule of the EUPI only), and ``"; ..."`` naming those left out
    ("" when none is).

    Why: ``smafl fit REC --memory from_top`` fitted the EUPI cascade for half a minute and then stopped with "unknown
    memory" on the Preisach classes, which have no such rule.  The first (default) class is never left out
    (``keep_first``): a rule it lacks is refused before any fit.
    """
    memory = options.get("memory", "auto")
    if memory in ("auto", "fitted", "rule"):
        return candidates, ""
    rules = {c: getattr(hysteresis_of(_label_start(c, record, options)), "RULE_INITS", ()) for c in candidates}
    if keep_first and memory not in rules[candidates[0]]:
        raise UserInputError(
            f"unknown memory {memory!r} for {candidates[0]}; choose auto, fitted, rule or one of {rules[candidates[0]]}"
        )
    kept = tuple(c for c in candidates if memory in rules[c])
    left = [c for c in candidates if c not in kept]
    if not left:
        return kept, ""
    return (
        kept,
        f"; memory {memory!r} is not a rule of {', '.join(left)}, so {'it was' if len(left) == 1 else 'they were'} not fitted",
    )


def _label_start(label, record, options):
    """The untrained model of an `auto_candidates` label (its class and options), to ask its class what it supports."""
    name, extra = candidate_model(label)
    return build_model(name, record, **{**(options.get("grid") or {}), **extra.get("grid", {})})


#: ``--model auto`` on a drive voltage keeps the default EUPI cascade (the paper's class) when another class wins the
#: validation block by less than this factor while the cascade fits the training samples at least as well.  Why: the
#: validation block is the last part of one record, a short extrapolation test; a Preisach class (hundreds of relays)
#: that edges out the cascade there although it fits the training part worse often extrapolates far worse on the rest.
#: Measured (session 47, held-out error of every class stored per record): on 36 records of EUPI-type plants (issue 18's
#: matrix and random multi-level drives, sessions 27-28) the rule switched 8, each held out as well or better (geometric
#: means of the groups 7.55 -> 4.66, 2.70 -> 2.70, 6.71 -> 5.41x the noise); on 24 records of a Preisach / Ikuta plant it
#: switched 2 (29.97 -> 24.66x, 2.19 -> 4.62x; the margin alone switched 4: 9.95 -> 11.72x).  On fresh seeds not used to
#: choose it: docs/identification.md, "The paper's class first (session 47)".
DEFAULT_CLASS_MARGIN = 2.0


def _val(run):
    return _rmse_or_inf(run[1].metrics["validation"])


def _train(run):
    m = run[1].metrics.get("train")
    return _rmse_or_inf(m) if m else np.inf


def _prefers_default(default, best):
    """The default class kept over ``best`` (`DEFAULT_CLASS_MARGIN`): within the margin on validation, no worse in training."""
    return _val(default) < DEFAULT_CLASS_MARGIN * _val(best) and _train(default) <= _train(best)


def _best(runs, prefer=None):
    """The run ``(name, candidate, seconds)`` with the lowest validation RMSE (the first of equals); with ``prefer`` (the
    default class's name, when it is among ``runs``) that class when `_prefers_default` says so."""
    best = min(runs, key=_val)
    default = next((r for r in runs if r[0] == prefer), None)
    return default if default is not None and best is not default and _prefers_default(default, best) else best


def _choice_reason(scored, name, prefer, validation):
    """How ``name`` was kept, for the note and fit.json ``structure_choice.on``."""
    best = min(scored, key=_val)
    d = next((r for r in scored if r[0] == prefer), None)
    if d is None or best is d:
        return f"lowest {validation} RMSE"
    if name == prefer:
        return (
            f"the default class: {best[0]}'s {validation} RMSE ({_val(best):.4g}) is not below 1/{DEFAULT_CLASS_MARGIN:g} of "
            f"{prefer}'s ({_val(d):.4g}) and {prefer} fits the training samples at least as well ({_train(d):.4g} vs "
            f"{_train(best):.4g}), so the paper's class is kept"
        )
    if _val(d) >= DEFAULT_CLASS_MARGIN * _val(best):
        return f"lowest {validation} RMSE"
    return (
        f"lowest {validation} RMSE; the default {prefer}, within {DEFAULT_CLASS_MARGIN:g}x of it, fits the training samples "
        f"worse ({_train(d):.4g} vs {_train(best):.4g})"
    )


def _finish_best_when_idle(pool, threads, futures, names, progress, prefer=None):
    """Once a thread goes idle while candidates are still being fitted (two threads, three candidates: the last one
    runs alone), start there the whole-record refit (``finish()``) of the best candidate fitted so far; returns
    ``{index: future of ((model, doc, extra), seconds)}`` (empty when nothing was started).

    `choose_structure` uses that refit when the candidate stays the best (it depends on the candidate alone, so the
    result is the one a refit after the choice makes), else it was work on a core that had none.  Measured on the
    benchmark record (2 cores): the Preisach candidate (about 5 s) ran alone after the other two, then the kept class's
    refit (about 5 s) alone."""
    if pool.pool is None:
        return {}
    waiting = set(futures)
    while waiting:
        _, waiting = concurrent.futures.wait(waiting, return_when=concurrent.futures.FIRST_COMPLETED)
        if not waiting or len(waiting) >= threads:  # every thread still has a candidate to fit
            continue
        done = [(names[i], f.result()[0], i) for i, f in enumerate(futures) if f.done()]
        scored = [r for r in done if r[1].metrics["validation"] is not None]
        if not scored:
            continue
        name, best, i = _best(scored, prefer=prefer)

        def refit():
            with tagged(name):
                say(
                    f"best so far: refitting {name} on the whole record now, on an idle thread (used if it stays the best)",
                    progress,
                )
                t0 = time.perf_counter()
                out = best.finish()
            return out, time.perf_counter() - t0

        return {i: pool.submit(refit)}
    return {}


def _submit_longest_first(pool, job, names, first=0):
    """``pool.submit(job, first + i, name)`` for each name, returned in the order of ``names``.  Submitted: the default
    candidate first (its thermal rate decides on the static classes), then the classes that refine jointly
    (`AbstractHysteresis.refine_jointly`: a gradient refinement after the start, the longer fits), then those whose
    profiled start is the fit.  Why: two classes that share a screening (`shared_screening`) cannot overlap it, so the
    one with more work after it should make it (measured on the benchmark record with 2 threads: the Preisach submitted
    before the Gaussian Preisach 98.3 s, after it 89.8 s)."""
    names = tuple(names)

    def joint(i):
        model = candidate_model(names[i])[0]  # the sparse companion refines as the default class it is
        h = model.removeprefix("cascade-")
        default = first == 0 and model == candidate_model(names[0])[0]
        return default or (h in HYSTERESIS and hysteresis_class(h).refine_jointly)

    order = sorted(range(len(names)), key=lambda i: not joint(i))  # stable: registry order within each group
    futures = {i: pool.submit(job, first + i, names[i]) for i in order}
    return [futures[i] for i in range(len(names))]


def candidate_threads(n: int) -> int:
    """How many candidates of ``--model auto`` are fitted at once: one per CPU core this process may use, at most
    ``n``.  Why: each candidate runs one compiled program at a time (one core), and the candidates are independent,
    so on 2 cores two of them take about the time of one (the results are those of fitting them one after another)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return max(1, min(int(n), cores))


class _Pool:
    """Runs submitted calls on ``threads`` threads (each in a copy of the submitter's context, so a `shared_screening`
    block reaches them), or at once in the calling thread with one thread.  Leaving the block after an error cancels
    the calls not yet started and waits for the running ones (no fit goes on behind the caller's back); after an
    interrupt (Ctrl-C) it does not wait."""

    def __init__(self, threads: int):
        self.pool = None if threads < 2 else concurrent.futures.ThreadPoolExecutor(threads, thread_name_prefix="smafl-candidate")

    def submit(self, fn, *args):
        if self.pool is not None:
            return self.pool.submit(contextvars.copy_context().run, fn, *args)
        done = concurrent.futures.Future()
        done.set_result(fn(*args))  # an error is raised here, before later candidates start, as it always was
        return done

    def __enter__(self):
        return self

    def __exit__(self, kind, *_):
        if self.pool is not None:
            self.pool.shutdown(wait=kind is None or issubclass(kind, Exception), cancel_futures=kind is not None)
        return False


def _on_side_thread(fn, *args) -> concurrent.futures.Future:
    """``fn(*args)`` started on a thread of its own, in a copy of the caller's context and with its progress tag."""
    tag, ctx = current_tag(), contextvars.copy_context()

    def run():
        if tag is None:
            return fn(*args)
        with tagged(tag):
            return fn(*args)

    pool = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="smafl-side")
    try:
        return pool.submit(ctx.run, run)
    finally:
        pool.shutdown(wait=False)  # the thread ends with its one call


def _rmse_or_inf(m):
    v = float(m["rmse"])
    return v if np.isfinite(v) else np.inf


def _validation_coverage(model, record, train, val):
    """`branch_coverage` of the validation samples on what the model's hysteresis sees: the fitted thermal state for a
    lag in front of the hysteresis (a PWM drive switches up and down every period, so its voltage covers every
    branch while the state it heats may only have risen in training), else the input itself."""
    x = effective_values(model, record.u, record.dt)
    what = "fitted model's hysteresis input (thermal state)"
    if x is None or not np.all(np.isfinite(x)):
        x, what = record.u, f"input '{record.input_name}'"
    return branch_coverage(x, train, val, what=what)


def _fit_structure(
    record,
    *,
    model="auto",
    split="auto",
    val_fraction=0.3,
    solver="lm",
    max_steps=300,
    thresholds=None,
    tilts=None,
    grid=None,
    orientation="auto",
    thermal_start="auto",
    sees="auto",
    memory="auto",
    refit=True,
    gain_prior=GAIN_PRIOR,
    progress=False,
    defer_refit=False,
    early_stopping=False,
    other_inputs=True,
    early_refit=False,
    slow_mode=False,
    warm_start=None,
    hold_input="auto",
):
    """`fit_record` of one structure (``model`` a name, or "auto" for the structure `auto_structure` names).

    ``other_inputs``: with validation samples, a cascade refines the hysteresis input the screening did not choose too
    (`screen_start`); `fit_record` turns it off for the classes other than the default one.

    ``defer_refit``: return a `Candidate` after the split fit, whose ``finish()`` makes the whole-record refit and
    fit.json, so that `choose_structure` refits only the class it keeps.  ``early_stopping``: the split fit's joint
    refinement stops on the validation samples (`_refine_early_stopped`; off by default: measured mixed, see there).
    ``early_refit`` (with ``defer_refit``; `fit_record` sets it for the default class): when the split refinement was
    rejected, the whole-record refit starts on a side thread before the split fit's polish (`Candidate.pending`).
    ``hold_input``: the split model is scored held to its training part's range by this rule (`hold_on`), as the saved
    model is held to the whole record's by `fit_record`.  ``slow_mode``: a cascade gets a slow thermal mode (`slow_thermal_start`), trained with the rest; ``warm_start`` (with
    ``slow_mode``): the same class's one-mode split fit, which the slow mode is added to (`slow_warm_start`) in place of
    the start screening (its output sign, hysteresis input and memory rule kept)."""
    if warm_start is not None and not slow_mode:
        raise ValueError("warm_start is the one-mode fit a slow thermal mode is added to: it needs slow_mode")
    if record.y is None:
        raise UserInputError(f"{record.path}: no output column to fit")
    if solver not in SOLVERS:
        raise UserInputError(f"unknown solver {solver!r}; choose one of {SOLVERS}")
    gain_prior = check_gain_prior(gain_prior)
    structure, thresholds, tilts, start, notes = structure_start(model, record, thresholds, tilts, grid, slow_mode)
    slow_mode = thermal_of(start) is not None and bool(slow_mode)
    max_steps = joint_steps(start, max_steps, notes)
    train, val, split_info = split_masks(record, split, val_fraction=val_fraction)
    if split_info.get("interpolated_left_out"):
        notes.append(interpolated_note([record]))
    # long Joule-driven records are fitted on a block-RMS view (see _decimate); metrics stay at the full rate
    rec, (tr, va), view_info = fit_view(record, start, [train, val])
    if view_info:
        notes.append(
            f"fitted on a view decimated by {view_info['stride']} ({view_info['n_samples']} samples at "
            f"{view_info['sample_time_s']:.4g} s: block-RMS drive, block-end output); metrics at the record's own rate"
        )
    t0 = time.perf_counter()
    screening, init, screen_info = None, "auto", {}
    memory_used = "fitted" if memory == "fitted" else "rule"
    if memory not in ("auto", "fitted", "rule", *getattr(hysteresis_of(start), "RULE_INITS", ())):
        raise UserInputError(f"unknown memory {memory!r}; choose auto, fitted, rule or one of the model's rules")
    if warm_start is not None and slow_mode:
        say("a slow thermal mode added to the one-mode split fit: searching it with the thermal rate and start", progress)
        start, init = slow_warm_start(warm_start, rec, [tr.astype(float)]), None
        memory_used = getattr(hysteresis_of(start), "init", memory_used)
        notes.append("slow thermal mode: started from this class's one-mode split fit (output sign, input, memory kept)")
    elif hysteresis_of(start) is not None:
        say("screening start candidates (output orientation, thermal start) on the training samples", progress)
        start, screening, screen_info = screen_start(
            start,
            rec,
            [tr.astype(float)],
            orientation=orientation,
            thermal_start=thermal_start,
            sees=sees,
            memory="rule" if memory == "auto" else memory,
            val_weights=[va.astype(float)] if va.any() else None,
            other_inputs=bool(other_inputs and va.any()),
            progress=progress,
        )
        init = None  # the screened start is already profiled
        choice = screen_info.get("structure_choice")
        if choice and any(c["sees"] is not None or c["memory"] is not None for c in choice["scores"]):
            notes.append(
                "start screening: "
                + ", ".join(
                    f"{k} {v}"
                    for k, v in (("hysteresis sees", choice["chosen"]["sees"]), ("memory rule", choice["chosen"]["memory"]))
                    if v
                )
                + f", chosen on {choice['on']} ("
                + ", ".join(
                    " ".join(str(x) for x in (c["sees"], c["memory"]) if x) + f" {c['score']:.4g}" for c in choice["scores"]
                )
                + ")"
            )

    def refine(start):
        spec = default_trainable(start, thresholds=thresholds, tilts=tilts)
        if early_stopping and init is None and va.any() and max_steps > LM_CHUNK:
            return _refine_early_stopped(start, spec, rec, tr, va, solver, max_steps, gain_prior, progress)
        res = fit(
            start, rec, solver=solver, trainable=spec, init=init, weights=[tr.astype(float)], max_steps=max_steps,
            gain_prior=gain_prior, progress=progress,
        )  # fmt: skip
        yhat = np.asarray(simulate(res.model, rec.u, rec.dt))
        if init is None and va.any() and res.n_steps > 0:
            if gain_prior is not None:  # the start compared with the same prior on its gains
                start = fit(start, rec, solver=None, init=None, weights=[tr.astype(float)], gain_prior=gain_prior).model
            # The joint refinement can buy training error with shapes that do not carry to new data
            # (measured on independent records: train 1.3x -> 1.0x noise, held-out 4x -> 15x). Keep it
            # only if it does not worsen the held-out error of the screened start.
            y0 = np.asarray(simulate(start, rec.u, rec.dt))
            e_ref = float(np.mean((yhat[va] - rec.y[va]) ** 2))
            e_start = float(np.mean((y0[va] - rec.y[va]) ** 2))
            if np.isfinite(e_start) and not e_ref <= e_start:
                return _rejected(res, start, y0, e_start, e_ref)
        return res, yhat, "kept", None

    def val_mse(yh):
        e = float(np.mean((yh[va] - rec.y[va]) ** 2))
        return e if np.isfinite(e) else np.inf

    # An output sign the profiled start could not decide (`screen_start`) goes on to the refinement too.
    starts = [start, *screen_info.get("alternatives", [])]

    def sign_of(m):
        return "rises" if hysteresis_of(m).orientation > 0 else "falls"

    # The hysteresis input the screening's score did not choose (`screen_start(other_inputs=True)`) is refined as well
    # and the validation samples decide between the inputs, as between the memories (see `screen_start`).
    input_alts = screen_info.get("input_alternatives", []) if init is None else []
    input_choice = None

    def memory_candidates(s):
        # the label is the rule the screening chose (descended / zero) or "fitted": the whole-record refit pins it
        out = [(getattr(hysteresis_of(s), "init", memory_used), s)]
        if memory == "auto" and va.any() and init is None:
            alt = fitted_memory_start(s, rec, [tr.astype(float)])
            if alt is not None:
                out.append(("fitted", alt[0]))
        return out

    def sees_of(m):
        return getattr(m, "sees", None)

    def train_mse(yh):
        e = float(np.mean((yh[tr] - rec.y[tr]) ** 2))
        return e if np.isfinite(e) else np.inf

    def best_run(rs):
        # one candidate (no validation samples, or memory fixed): nothing to choose, and no mean over an empty set
        return rs[0] if len(rs) == 1 else min(rs, key=lambda r: val_mse(r[2]))

    picks, memory_runs = [], []
    for j, s in enumerate(starts):
        by_input = [[(label, *refine(m)) for label, m in memory_candidates(a)] for a in [s, *(input_alts if j == 0 else [])]]
        runs = [r for rs in by_input for r in rs]
        # The screened input's best run, unless the other input's best is lower on validation and fits the training
        # samples no worse (as `_prefers_default` keeps the default class): a flexible structure can win one validation
        # block and extrapolate worse (session 49: plant A s229, validation 0.0755 vs 0.1101 for the heat, training
        # 1.30x vs 1.04x the noise, held out 11.1x vs 2.6x).
        bests = [best_run(rs) for rs in by_input]
        pick = bests[0]
        for b in bests[1:]:
            if val_mse(b[2]) < val_mse(pick[2]) and train_mse(b[2]) <= train_mse(bests[0][2]):
                pick = b
        picks.append(pick)
        # the pick's input: its memories (the spread compares them); by identity, the runs hold arrays
        memory_runs.append(next(rs for rs, b in zip(by_input, bests) if b is pick))
        if len(runs) > 1:
            # A fitted operator memory helps a record that starts on an unknown branch and hurts where the extra
            # freedom extrapolates (NiTi water steps: validation RMSE 6.8 -> 18.8); the validation samples decide.
            shown_input = len(by_input) > 1
            notes.append(
                (f"output {sign_of(s)}: " if len(starts) > 1 else "")
                + ("hysteresis input and " if shown_input else "")
                + "operator memory at t = 0: "
                + ", ".join(
                    (f"{sees_of(run[1].model)} " if shown_input else "")
                    + f"{run[0]} (validation RMSE {np.sqrt(val_mse(run[2])):.4g}"
                    + (f", training {np.sqrt(train_mse(run[2])):.4g}" if shown_input else "")
                    + ")"
                    for run in runs
                )
                + f" -> {(sees_of(pick[1].model) + ' ') if shown_input else ''}{pick[0]}"
                + (
                    "; the other input is kept only when it is lower on validation and no higher on training"
                    if shown_input
                    else ""
                )
            )
            if shown_input:
                input_choice = {
                    "chosen": sees_of(pick[1].model),
                    "screened": sees_of(s),
                    "on": "validation RMSE of the refined split fits; the other input only if no higher on training",
                    "runs": [
                        {
                            "sees": sees_of(run[1].model),
                            "memory": run[0],
                            "validation_rmse": float(np.sqrt(val_mse(run[2]))),
                            "train_rmse": float(np.sqrt(train_mse(run[2]))),
                        }
                        for run in runs
                    ],
                }
    do_refit = refit and val.any() and hysteresis_of(start) is not None

    def deploy(pick):
        """The split fit's choices refitted on every sample (polished at the full rate after a view fit)."""
        final = _refit_whole(
            rec, structure, pick[1].model, grid, thermal_start, pick[3], solver, max_steps, thresholds, tilts, progress,
            pick[0], gain_prior, chunked=early_stopping, slow_mode=slow_mode, warm=warm_start is not None,
        )  # fmt: skip
        if view_info and max_steps > 0:
            final = _polish(final, record, record.measured, solver, thresholds, tilts, progress, gain_prior)
        return final

    finals = {}
    chosen = 0
    if len(picks) > 1:
        if do_refit:
            # Equal parameter counts: the sign whose whole-record fit has the lower training error wins.
            # Why not the validation block: it walks branches the training part never saw (measured on an
            # independent warm step-train record: validation preferred "falls", 8x vs 15x noise, whose whole-record
            # fit then stayed at 3.2x noise on its own training data and 22x on new data; "rises": 1.2x and 3.1x).
            finals = {i: deploy(p) for i, p in enumerate(picks)}
            ok = record.measured
            sse = {
                i: float(np.sum((np.asarray(simulate(m, record.u, record.dt)) - record.y)[ok] ** 2)) for i, m in finals.items()
            }
            sse = {i: v if np.isfinite(v) else np.inf for i, v in sse.items()}
            chosen = min(sse, key=lambda i: sse[i])
            how = "whole-record training RMSE " + ", ".join(
                f"{sign_of(picks[i][1].model)} {np.sqrt(v / ok.sum()):.4g}" for i, v in sse.items()
            )
        elif va.any():
            chosen = min(range(len(picks)), key=lambda i: val_mse(picks[i][2]))
            how = "validation RMSE " + ", ".join(f"{sign_of(p[1].model)} {np.sqrt(val_mse(p[2])):.4g}" for p in picks)
        else:  # no held-out samples: the training error of the refined fits (equal parameter counts)
            mse = [float(np.mean((p[2][tr] - rec.y[tr]) ** 2)) for p in picks]
            chosen = int(np.nanargmin(mse))
            how = "training RMSE " + ", ".join(f"{sign_of(p[1].model)} {np.sqrt(v):.4g}" for p, v in zip(picks, mse))
        notes.append(
            f"output orientation: the profiled start could not decide; each was refined and the one with the lower "
            f"{how.split(' RMSE ')[0]} RMSE kept ({how}) -> {sign_of(picks[chosen][1].model)}"
        )
    label, res, yhat, refinement, note = picks[chosen]
    memory_used = label
    if note:
        notes.append(note)
    early, hold_check = None, None
    if early_refit and do_refit and refinement != "kept" and chosen not in finals and candidate_threads(2) > 1:
        # A split refinement rejected on validation: the whole-record refit screens afresh on every sample and takes
        # only the split fit's structure (output sign, hysteresis input, memory rule), which the polish below does not
        # change, so it starts now on a core of its own (the same refit, bit for bit).  Measured on the benchmark record
        # (2 cores): the default cascade's polish and its refit ran one after the other, the other core idle.
        early = _on_side_thread(deploy, (label, res, yhat, refinement))
    try:
        spread = _memory_spread(memory_runs[chosen], rec, record.y[train], notes) if len(memory_runs[chosen]) > 1 else None
        if view_info and max_steps > 0:
            res = res._replace(model=_polish(res.model, record, train, solver, thresholds, tilts, progress, gain_prior))
        # scored (and compared with the other classes) as the saved model will run: held to its training part's range,
        # unless the validation samples, where they leave that range, are predicted better extrapolating (`hold_choice`)
        held = hold_on(res.model, [(record, train)], hold_input)
        if held is not res.model and val.any():
            ok = val & record.measured
            sse = [
                float(np.sum((np.asarray(simulate(m, record.u, record.dt))[ok] - record.y[ok]) ** 2)) for m in (held, res.model)
            ]
            way, hold_check = hold_choice(*sse, int(ok.sum()), hold_input, "the validation samples")
            held = held if way == "held" else res.model
        res = res._replace(model=held)
        yhat = np.asarray(simulate(res.model, record.u, record.dt))  # at the record's own rate
        if not np.all(np.isfinite(yhat)):
            raise UserInputError(f"{record.path}: the fitted model gives non-finite output ({res.message})")
    except BaseException:
        if early is not None:  # an error or an interrupt: no refit goes on behind the caller's back
            early.cancel() or concurrent.futures.wait([early])
        raise
    seconds = time.perf_counter() - t0
    mets = {
        "train": metrics(record.y[train], yhat[train]),
        "validation": metrics(record.y[val], yhat[val]) if val.any() else None,
    }
    split_model = res.model
    if val.any():
        split_info = {**split_info, "coverage": _validation_coverage(split_model, record, train, val)}
        if "warning" in split_info["coverage"]:
            notes.append("validation coverage: " + split_info["coverage"]["warning"])

    def finish():
        """The whole-record refit (when asked) and fit.json: ``(model, doc, (train, val, yhat))``."""
        final = split_model
        if do_refit:
            # The split chose the structure (orientation, hysteresis input, refinement or not) and measured
            # the held-out error; the model a user deploys is then fitted on every sample with those choices.
            # On independent cold-start records a fit starved of the last 30 % extrapolated 10-50x worse.
            if chosen in finals:
                final = finals[chosen]
            else:
                final = early.result() if early is not None else deploy((label, res, yhat, refinement))
            y_all = np.asarray(simulate(final, record.u, record.dt))
            mets["whole_record"] = _whole_record(record, y_all)
            notes.append(
                "validation metrics are those of the model fitted on the training samples only; the saved model is refitted "
                "on the whole record with the same structure choices (split model in fit.json 'split_model'; --no-refit keeps it)"
            )
        mets["noise"] = noise_floor(
            [record], train=mets["train"], validation=mets["validation"], whole_record=mets.get("whole_record")
        )
        note = noise_floor_note(mets["noise"])
        if note:
            notes.append(note)
        if thermal_of(final) is not None:  # a thermal lag in front of a hysteresis: k2 cancels (a cascade)
            notes.append(K2_NOTE)
            prof = (res.info or {}).get("profile") or screen_info.get("profile") or {}
            if prof.get("at_grid_edge"):
                notes.append(
                    f"the best k1 ({prof.get('k1'):.4g} 1/s) lies at the edge of the candidate grid: the record does not "
                    "pin down the thermal time constant (e.g. quasi-static data)"
                )
        gp = (res.info or {}).get("gain_prior")
        if gp and gp["largest_gain"] < 0.5 * gp["largest_gain_free"]:
            # worth saying: the prior changed what a user will see on a new run (`smafl_jax.identify._gain_prior`)
            notes.append(
                f"gain prior (kappa {gp['kappa']:g}, --gain-prior): largest operator gain {gp['largest_gain_free']:.4g} -> "
                f"{gp['largest_gain']:.4g} against an output range of {gp['output_range']:.4g} (training RMSE "
                f"{gp['rmse_free']:.4g} -> {gp['rmse']:.4g}): gains far beyond the output range that cancel the offset "
                "break on a new run; --gain-prior none keeps the least-squares gains"
                + (
                    f"; {gp['weak_columns']} operator(s) that barely moved over the training samples got gain 0"
                    if gp.get("weak_columns")
                    else ""
                )
            )
        if not res.converged:
            notes.append(f"solver: {res.message}")
        doc = {
            **fit_header(final),
            "split_model": model_to_dict(split_model) if final is not split_model else None,
            "metrics": mets,
            "data": record_data(record),
            "split": split_info,
            "settings": {
                "model": model,
                "structure": structure,
                "orientation": orientation,
                "thermal_start": thermal_start,
                "sees": sees,
                "memory": memory,
                "memory_used": memory_used,
                "memory_spread": spread,
                "hold_input_check": hold_check,
                "input_choice": input_choice,
                "start_screening": screening,
                "split": split_info["kind"],
                "val_fraction": val_fraction,
                "solver": solver,
                "max_steps": max_steps,
                "train_thresholds": thresholds,
                "train_tilts": tilts,
                "grid": grid or {},
                "init": (res.info or {}).get("init"),
                "fit_view": view_info,
                "gain_prior": gain_prior,
                "early_stopping": early_stopping,
                "slow_thermal_mode": slow_mode,
            },
            "solver": solver_entry(
                res,
                seconds,
                refinement=refinement,
                profile_k1=((res.info or {}).get("profile") or screen_info.get("profile") or {}).get("k1"),
                gain_prior=(res.info or {}).get("gain_prior"),
                early_stopping=(res.info or {}).get("early_stopping"),
            ),
            "notes": notes,
            "versions": versions(),
        }
        from ..identify._multi_record import add_record_extras  # baselines, data checks, loading notes, training input range

        # the saved model's own training samples: every sample after the whole-record refit, else the split's training part
        fitted_on = np.ones(len(record), bool) if final is not split_model else train
        add_record_extras(doc, record, train, val, yhat, fitted_on=fitted_on)
        eff = effective_range([(final, record.u, record.dt, fitted_on)])
        if eff is not None:
            # what the saved model's hysteresis saw in training: simulate/control/sweep warn when a new input leaves it
            doc["data"]["effective_input_range"] = eff
            doc["data"]["effective_input_range_rule"] = EFFECTIVE_RULE
        x_h = hysteresis_values(final, record.u, record.dt)  # a direct-input hysteresis walks the input's own branches
        if x_h is not None and np.all(np.isfinite(x_h)):
            doc["data"]["trained_branches"] = trained_branches(x_h, fitted_on)
        return final, doc, (train, val, yhat)

    if defer_refit:
        profile_k1 = ((res.info or {}).get("profile") or screen_info.get("profile") or {}).get("k1")
        covered = (split_info.get("coverage") or {}).get("covered_fraction")
        return Candidate(split_model, mets, profile_k1, finish, covered, early)
    return finish()


#: Joint LM steps between two looks at the validation error in the split fit's refinement (`_refine_early_stopped`).
LM_CHUNK = 50
#: Chunks in a row without a lower validation error after which the refinement stops.
LM_PATIENCE = 2


def _lm_chunks(model, spec, rec, weights, solver, total, gain_prior, progress, look=None):
    """Up to ``total`` joint steps from ``model`` in chunks of `LM_CHUNK` (one compiled solve serves every chunk); the
    gain prior is applied to each chunk's iterate, as the returned model has it.  ``look(model) -> float`` (optional):
    called on each such model; the one with its lowest value is kept (the start counts, as 0 steps) and the run stops
    after `LM_PATIENCE` chunks without a new lowest.  Returns ``(FitResult, best_steps, steps_run, looks)``; the
    result's ``n_steps`` is ``best_steps``."""

    def with_prior(m):
        return fit(m, rec, solver=None, init=None, weights=weights, gain_prior=gain_prior)

    best = (np.inf, model, 0)
    if look is not None:
        first = with_prior(model)
        best = (look(first.model), first, 0)
    looks, cur, steps, stale, converged = [], model, 0, 0, False
    while steps < total:
        r = fit(
            cur, rec, solver=solver, trainable=spec, init=None, weights=weights, max_steps=min(LM_CHUNK, total - steps),
        )  # fmt: skip
        steps += r.n_steps
        converged, moved, cur = r.converged, r.model is not cur, r.model
        if look is None:
            best = (np.inf, cur, steps)
        else:
            got = with_prior(cur)
            looks.append((steps, look(got.model)))
            say(f"  joint refinement: {steps} steps, validation RMSE {np.sqrt(looks[-1][1]):.6g}", progress)
            if looks[-1][1] < best[0]:
                best, stale = (looks[-1][1], got, steps), 0
            else:
                stale += 1
        if converged or not moved or r.n_steps == 0 or stale >= LM_PATIENCE:
            break
    res = best[1] if look is not None else with_prior(best[1])
    message = "converged" if converged and best[2] == steps else f"{solver}: {best[2]} steps kept of {steps} run"
    return res._replace(n_steps=best[2], converged=converged, message=message, solver=solver), best[2], steps, looks


#: Noise SDs (RMS) by which the rule- and fitted-memory fits may part on sweeps of the trained range before a note says so.
SPREAD_WARN = 3.0


def _memory_spread(runs, rec, y_train, notes):
    """fit.json ``settings.memory_spread``: how far the split fits with the rule's and the fitted operator memory part on
    sweeps of the trained input range after the record (`sweep_spread`), in output units and noise SDs; a note when
    they part by more than `SPREAD_WARN` SDs (the record leaves the response on branches it did not walk open)."""
    (la, ra, *_), (lb, rb, *_) = runs[0], runs[1]
    out = {"models": [la, lb], **sweep_spread(ra.model, rb.model, rec.u, rec.dt)}
    sd = noise_floor([y_train])["sd"]
    out["noise_sd"] = sd
    out["rms_ratio"] = out["rms"] / sd if sd else None
    if out["rms_ratio"] is not None and not out["rms_ratio"] <= SPREAD_WARN:
        notes.append(
            f"{BRANCHES_OPEN} the split fits with {la} and {lb} operator memory part by {out['rms_ratio']:.3g}x the noise SD "
            f"(RMS; largest {out['max']:.4g}) on {out['sweeps']} slow sweeps of the trained input range after the record, "
            "while fitting its samples alike: the record does not determine the response on branches it did not walk, "
            "and a new drive that walks them may see errors of that size (fit.json settings.memory_spread)"
        )
    return out


def _rejected(res, start, y0, e_start, e_ref):
    """The split refinement rejected on validation: the screened start is kept (``refine``'s 4-tuple)."""
    note = (
        f"the joint refinement lowered the training error but raised the validation RMSE "
        f"({np.sqrt(e_start):.4g} -> {np.sqrt(e_ref):.4g}); kept the screened (profiled) start model"
    )
    res = res._replace(model=start, loss=res.init_loss, message=res.message + "; refinement rejected on validation")
    return res, y0, "rejected", note


def _refine_early_stopped(start, spec, rec, tr, va, solver, max_steps, gain_prior, progress):
    """The split fit's joint refinement with early stopping on the validation samples: `LM_CHUNK` steps at a time, the
    iterate with the lowest validation error kept, stopped after `LM_PATIENCE` chunks without a lower one; the start
    itself (0 steps) competes, so a refinement that only worsens the validation error is rejected as before.
    ``info["early_stopped_at"]`` records the kept step count; the whole-record refit still runs up to ``max_steps``
    (capping it there lost on the records below: s7 steps 25 Hz 3.7x -> 20.5x noise held out).  Why: a refinement run
    to the 300-step cap can go past its best held-out point (a fresh plant-B record, Gaussian Preisach cascade:
    validation RMSE 0.00565 at the start, 0.00505 after 50 steps, 0.00512 after 100, worse than the start by 200, so
    the whole refinement was rejected).  Off by default (``fit_record(early_stopping=True)``): on 16 fresh plant-B records
    (seeds 6-7, 5 and 25 Hz; deployed model scored on the unseen last 30 %) auto over three classes 8.06x -> 7.72x noise
    and the EUPI and Gaussian-Preisach fits 17-19 % faster, but the EUPI cascade alone 18.4x -> 20.4x (3 worse) and the
    Gaussian Preisach alone 6.58x -> 7.68x (3 better, one 7.7x -> 222x: a record whose rejected refinement used to send
    the whole-record refit to a fresh screening; experiments/results/class_choice_confirm_session23_early_stop_*.jsonl)."""
    w = [tr.astype(float)]
    if gain_prior is not None:  # the start compared with the same prior on its gains
        start = fit(start, rec, solver=None, init=None, weights=w, gain_prior=gain_prior).model

    def val_sq(m):
        e = float(np.mean((np.asarray(simulate(m, rec.u, rec.dt))[va] - rec.y[va]) ** 2))
        return e if np.isfinite(e) else np.inf

    e_start = val_sq(start)
    say(f"joint refinement: {solver}, up to {max_steps} steps, early stopping on the validation samples", progress)
    res, kept, run, looks = _lm_chunks(start, spec, rec, w, solver, max_steps, gain_prior, progress, look=val_sq)
    res = res._replace(init_loss=fit(start, rec, solver=None, init=None, weights=w).loss)
    res = res._replace(
        info={**(res.info or {}), "early_stopping": {"steps_run": run, "steps_kept": kept, "validation_mse": looks}}
    )
    if kept == 0:
        y0 = np.asarray(simulate(start, rec.u, rec.dt))
        return _rejected(res, start, y0, e_start, min(v for _, v in looks) if looks else e_start)
    res = res._replace(info={**res.info, "early_stopped_at": kept})
    return res, np.asarray(simulate(res.model, rec.u, rec.dt)), "kept", None


#: Full-rate LM steps after a fit on the decimated view (`_decimate`).
POLISH_STEPS = 10


def _polish(model, record, mask, solver, thresholds, tilts, progress, gain_prior=None):
    """A few joint LM steps at the record's own rate from a model fitted on the decimated view.

    The view is exact for the heat per block, but a plant integrates its drive in its own way inside a
    sample; measured on an independent PWM record (25 Hz, stride 2): the view's model was at 1.09x noise
    on the view and 19x at the full rate, and 10 full-rate steps (5 s) brought it to 1.09x.
    """
    spec = default_trainable(model, thresholds=thresholds, tilts=tilts)
    res = fit(
        model, record, solver=solver, trainable=spec, init=None, weights=[mask.astype(float)], max_steps=POLISH_STEPS,
        gain_prior=gain_prior,
    )  # fmt: skip
    say(f"full-rate polish of the view's fit: loss {res.init_loss:.6g} -> {res.loss:.6g} ({res.n_steps} steps)", progress)
    return res.model


def _whole_record(record, y_all):
    """Metrics of the saved model over the record's measured samples (None on non-finite output)."""
    ok = record.measured
    return metrics(record.y[ok], y_all[ok]) if np.all(np.isfinite(y_all)) else None


def _refit_whole(
    record,
    structure,
    chosen,
    grid,
    thermal_start,
    refinement,
    solver,
    max_steps,
    thresholds,
    tilts,
    progress,
    memory="fitted",
    gain_prior=None,
    chunked=False,
    slow_mode=False,
    warm=False,
):
    """The split fit's structure choices, refitted on every sample of the record (``chunked``: a kept refinement's warm
    refit in `LM_CHUNK`-step chunks, as an early-stopped split refinement ran; ``warm``: a rejected refinement's refit
    starts from the split fit's thermal state re-searched on every sample, not from a fresh screening, as the split fit
    started from a one-mode fit, `slow_warm_start`)."""
    # the output sign in the line: an undecided sign refits both (`deploy`), which read as the same refit said twice
    sign = getattr(hysteresis_of(chosen), "orientation", 1)
    say(f"refitting the chosen structure on the whole record (output {'rises' if sign > 0 else 'falls'})", progress)
    ones = [record.measured.astype(float)]  # every measured sample (none a resampling interpolated)
    if refinement == "kept" and max_steps > 0:
        # warm start from the split's refined model: the whole-record optimum is close, LM needs few steps
        spec = default_trainable(chosen, thresholds=thresholds, tilts=tilts)
        if chunked:  # as the early-stopped split refinement ran (`_lm_chunks`: one compiled solve)
            return _lm_chunks(chosen, spec, record, ones, solver, max_steps, gain_prior, progress)[0].model
        res = fit(
            chosen, record, solver=solver, trainable=spec, init=None, weights=ones, max_steps=max_steps,
            gain_prior=gain_prior, progress=progress,
        )  # fmt: skip
        return res.model
    if warm:
        _, start, _ = refine_thermal_start(chosen, record, ones, float(np.max(np.asarray(record.u))))
        return _joint_refit(start, record, ones, solver, max_steps, thresholds, tilts, gain_prior, progress)
    e = chosen.hysteresis
    start, _, _ = screen_start(
        build_model(structure, record, **(grid or {}), slow_mode=slow_mode),
        record,
        ones,
        orientation="rises" if e.orientation > 0 else "falls",
        thermal_start=thermal_start,
        sees=getattr(chosen, "sees", "auto"),
        memory=memory,
        progress=progress,
    )
    if not hysteresis_of(chosen).refine_jointly:
        start = _warm_refit(chosen, start, record, ones, progress)
    return _joint_refit(start, record, ones, solver, max_steps, thresholds, tilts, gain_prior, progress)


def _joint_refit(start, record, ones, solver, max_steps, thresholds, tilts, gain_prior, progress):
    """`_refit_whole`'s last step: the joint refinement from a profiled start on every sample (the gain prior alone when
    the class has none)."""
    if max_steps > 0:
        # the split's refinement may have been rejected on a validation block the training part never
        # reached; with every sample the joint refinement has the data it lacked (independent multisine
        # record: held-out 26x -> 18x noise against the profiled start alone)
        spec = default_trainable(start, thresholds=thresholds, tilts=tilts)
        return fit(
            start, record, solver=solver, trainable=spec, init=None, weights=ones, max_steps=max_steps,
            gain_prior=gain_prior, progress=progress,
        ).model  # fmt: skip
    if gain_prior is not None:
        return fit(start, record, solver=None, init=None, weights=ones, gain_prior=gain_prior).model
    return start


def _warm_refit(chosen, fresh, record, ones, progress):
    """For a class without gradient refinement (`refine_jointly` False): the split fit's own thermal rate and start,
    profiled again on every sample, against the fresh screening ``fresh``; the lower whole-record loss is kept.

    Why: nothing else carries the split's fit over, and the fresh search (orientation, input and rule pinned, a few
    thermal starts) can stop in a worse optimum (measured on the benchmark record, a Preisach cascade: whole-record
    profiled loss 0.0924 fresh, 0.0834 from the split fit's state)."""
    th = thermal_of(chosen)
    if th is not None and th.init == "given":
        loss, warm, _ = refine_thermal_start(chosen, record, ones, float(np.max(np.asarray(record.u))))
    else:
        res = fit(chosen, record, solver=None, init="linear", weights=ones)
        loss, warm = res.loss, res.model
    fresh_loss = fit(fresh, record, solver=None, init=None, weights=ones).loss
    keep = warm if np.isfinite(loss) and loss < fresh_loss else fresh
    say(
        f"whole-record start: the split fit's thermal state re-profiled (loss {loss:.6g}) vs a fresh screening "
        f"({fresh_loss:.6g}) -> {'the split fit' if keep is warm else 'fresh'}",
        progress,
    )
    return keep


# -- report ---------------------------------------------------------------------------


def _figures(out, record, yhat, train, val):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ._reportdoc import axis_label

    t, u, y = record.time, record.u, record.y
    units = getattr(record, "units", None)
    yname = axis_label(record.output_name or "output", units)  # "displacement (mm)"; says so when no unit is known
    uname = axis_label(record.input_name or "input", units)
    files = {}

    fig, ax = plt.subplots(figsize=(9, 3.6))
    ax.plot(t, y, lw=1.0, color="0.2", label="measured")
    ax.plot(t, yhat, lw=1.0, color="C1", label="model")
    if val.any():
        ax.fill_between(t, np.min(y), np.max(y), where=val, color="C0", alpha=0.12, step="mid", label="validation")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(yname)
    ax.legend(loc="best", fontsize=8)
    files["time"] = "fit_time.png"
    atomic_savefig(fig, out / files["time"])
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(5.5, 4.5))
    ax.plot(u[train], y[train], ".", ms=2, color="0.3", label="measured (train)")
    if val.any():
        ax.plot(u[val], y[val], ".", ms=2, color="C0", label="measured (validation)")
    ax.plot(u, yhat, lw=0.9, color="C1", label="model")
    ax.set_xlabel(uname)
    ax.set_ylabel(yname)
    ax.legend(loc="best", fontsize=8)
    files["loops"] = "fit_loops.png"
    atomic_savefig(fig, out / files["loops"])
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(9, 3.0))
    err = y - yhat
    ax.plot(t[train], err[train], ".", ms=2, color="0.3", label="train")
    if val.any():
        ax.plot(t[val], err[val], ".", ms=2, color="C0", label="validation")
    ax.axhline(0, color="k", lw=0.6)
    ax.set_xlabel("time (s)")
    ax.set_ylabel(axis_label(record.output_name or "output", units, prefix="residual "))
    ax.legend(loc="best", fontsize=8)
    files["residuals"] = "fit_residuals.png"
    atomic_savefig(fig, out / files["residuals"])
    plt.close(fig)
    return files


def _fmt(x):
    return "n/a" if x is None else f"{x:.4g}"


def _report_md(doc, files):
    d, s, sv = doc["data"], doc["settings"], doc["solver"]
    m = doc["model"]
    lines = [
        f"# Fit of `{d['file']}` ({s['model']})",
        "",
        f"- data: `{d['path']}` (sha256 `{d['sha256']}`), input `{d['input_column']}`, output `{d['output_column']}`, "
        f"dt {d['sample_time_s']:g} s, {d['n_samples']} samples",
        f"- split: {doc['split']['rule']}",
        *([f"- **Warning:** {doc['split']['coverage']['warning']}"] if doc["split"].get("coverage", {}).get("warning") else []),
        *[f"- loading: {note}" for note in d.get("processing", [])],
        f"- solver: {sv['name']} ({sv['n_steps']} steps, {sv['seconds']:.1f} s): {sv['message']}",
        "",
        "| metric | train | validation |",
        "| --- | --- | --- |",
    ]
    tr, va = doc["metrics"]["train"], doc["metrics"]["validation"] or {}
    for key, label in [
        ("rmse", "RMSE"),
        ("e_r_percent", "e_r (eq. 3, %)"),
        ("max_abs_error", "max abs error"),
        ("mean_abs_error", "mean abs error"),
        ("n_samples", "samples"),
    ]:
        lines.append(f"| {label} | {_fmt(tr.get(key))} | {_fmt(va.get(key))} |")
    noise = doc["metrics"].get("noise")
    if noise:  # fit.json files written before session 28 have none
        lines.append(f"| RMSE / output noise SD | {_fmt(noise.get('train_ratio'))} | {_fmt(noise.get('validation_ratio'))} |")
        lines += ["", f"Output noise SD {_fmt(noise['sd'])}, estimated from the data: {noise['method']}."]
    from ..identify._baselines import baselines_markdown
    from ..identify._multi_record import data_checks_markdown

    med = doc.get("median")
    if med and (med["metrics"].get("validation") or {}).get("rmse") is not None:
        lines += [
            "",
            f"Median of the classes ({', '.join(med['members'])}; `{med.get('file', 'median_fit.json')}`): validation RMSE "
            f"{_fmt(med['metrics']['validation']['rmse'])}, e_r {_fmt(med['metrics']['validation']['e_r_percent'])} %.",
        ]
    lines += baselines_markdown(doc.get("baselines"), doc["metrics"]["validation"], doc["metrics"]["train"])
    lines += data_checks_markdown(doc.get("data_checks"))
    lines += ["", "## Parameters", ""]
    # the saved model states its own key parameters (`describe`: thermal rates, hysteresis weights...); a model
    # class without that method has only the pointer to fit.json
    describe = getattr(model_from_dict(m, where=f"{d['file']}: model"), "describe", None)
    lines += [f"- {line}" for line in (describe() if describe is not None else [])]
    lines.append("- full parameters: `fit.json`")
    if doc["notes"]:
        lines += ["", "## Notes", ""] + [f"- {n}" for n in doc["notes"]]
    lines += ["", "## Figures", ""]
    for key, title in [
        ("time", "Measured vs model over time"),
        ("loops", "Hysteresis loops (input vs output)"),
        ("residuals", "Residuals"),
    ]:
        if key in files:
            lines += [f"### {title}", "", f"![{title}]({files[key]})", ""]
    return "\n".join(lines) + "\n"


def write_fit_outputs(out, record, doc, masks, *, figures=True):
    """Write ``fit.json``, ``report.md`` and the figures into folder ``out``."""
    out = Path(out)
    train, val, yhat = masks
    files = _figures(out, record, yhat, train, val) if figures else {}
    doc = dict(doc, figures=files)
    if doc.get("median"):  # its own fit.json-format file, so `smafl simulate median_fit.json NEW.csv` runs it
        atomic_write_json(out / "median_fit.json", doc["median"])
        doc["median"] = {"file": "median_fit.json", "members": doc["median"]["members"], "metrics": doc["median"]["metrics"]}
    atomic_write_json(out / "fit.json", doc)
    atomic_write_text(out / "report.md", _report_md(doc, files))
    return doc
