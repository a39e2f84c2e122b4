"""Posterior sampling of a fitted model as one library call (the workflow behind ``smafl sample``).

`sample_posterior` loads the record(s) and the fit, builds the `Posterior` (several records: one model, each record
run from its own start: the joint fit's fitted start for its training records, the fit's start rule for others)
(choosing how the hysteresis weights are handled), runs emcee with the HDF5
backend (resuming a chain of the same settings, refusing one of other settings
unless ``restart``), summarises the chain and writes, atomically, to ``out``:
``chain.h5``, ``run.json`` (the settings the chain belongs to),
``summary.json``, ``parameters.csv``, ``corner.png``, ``trace.png``,
``predictive_time.png``, ``predictive_loop.png`` and ``predictive.csv``.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from .._errors import UserInputError

if TYPE_CHECKING:
    from ..bayes._bayes import Posterior, Prior, SampleRun
    from ..data._data import Record

PathLike = str | os.PathLike

__all__ = ["SamplingResult", "sample_posterior", "FILES"]

LOGGER = logging.getLogger(__name__)

#: The files `sample_posterior` writes to its output folder (besides emcee's ``chain.h5.bak`` checkpoint).
FILES = (
    "chain.h5",
    "run.json",
    "summary.json",
    "parameters.csv",
    "corner.png",
    "trace.png",
    "predictive_time.png",
    "predictive_loop.png",
    "predictive.csv",
)

# How error messages name the settings; the command line passes its flags instead (``--steps``...).
_OPTION_NAMES = {
    "steps": "steps",
    "walkers": "walkers",
    "burn": "burn",
    "draws": "draws",
    "holdout_fraction": "holdout_fraction",
    "gain_scale": "gain_scale",
    "nu": "nu",
    "linear": "linear",
    "restart": "restart=True",
    "out": "out",
}


class SamplingResult(NamedTuple):
    """What `sample_posterior` produced: the ``summary`` written to summary.json, the output folder,
    the written files by name, the `Posterior` and the chain (`SampleRun`)."""

    summary: dict
    out: Path
    files: dict[str, Path]
    posterior: Posterior
    run: SampleRun


def _record_file(rec) -> str:
    return Path(rec.path).name if rec.path else rec.name


def _load_fit(fit):
    """``(model, fit.json document, sha256, label)`` from a fit.json / model file path or a model object."""
    from .._io import load_model_file, model_to_dict

    if isinstance(fit, (str, os.PathLike)):
        model, doc = load_model_file(fit)
        return model, doc, hashlib.sha256(Path(fit).read_bytes()).hexdigest(), str(fit)
    try:
        blob = json.dumps(model_to_dict(fit), sort_keys=True).encode()
    except (TypeError, ValueError, KeyError) as exc:
        raise UserInputError(f"fit: expected a fit.json path or a saved-model type, got a {type(fit).__name__} ({exc})") from None
    return fit, {}, hashlib.sha256(blob).hexdigest(), None


def _load_records(record, *, input=None, output=None, time=None, resample=None, window=None) -> list:
    """The records to condition on: a CSV path, folder or glob, a `Record`, or a sequence of them (one column choice).
    ``resample`` (seconds or "auto") puts the files' irregular stamps on a uniform grid; ``window`` ``(start, end)``
    seconds cuts every record (`Record.window`)."""
    from ..data._data import Record
    from ..data.load import load_records

    items = list(record) if isinstance(record, (list, tuple)) else [record]
    if not items:
        raise UserInputError("no record given to condition on")
    bad = [type(x).__name__ for x in items if not isinstance(x, (str, os.PathLike, Record))]
    if bad:
        raise UserInputError(f"expected CSV paths or Records, got a {bad[0]}")
    paths = [x for x in items if not isinstance(x, Record)]
    # the files first (one column choice, folders and globs expanded, units checked alike), then the Records given
    recs = (load_records(paths, input=input, output=output, time=time, resample=resample) if paths else []) + [
        x for x in items if isinstance(x, Record)
    ]
    if window is not None:
        recs = [r.window(*window) for r in recs]
    first = recs[0]
    for r in recs[1:]:
        if (r.input_name, r.output_name) != (first.input_name, first.output_name):
            raise UserInputError(
                f"{r.name}: columns ({r.input_name}, {r.output_name}) differ from {first.name}'s "
                f"({first.input_name}, {first.output_name}); all records need the same columns"
            )
    seen = {}
    for r in recs:
        if r.sha256 and r.sha256 in seen:
            raise UserInputError(f"{r.name} has the same content as {seen[r.sha256]}: a record conditioned on twice counts twice")
        seen.setdefault(r.sha256, r.name)
    return recs


def _starts(model, doc, recs):
    """``(model, per-record start rows, new-record start)``: ``model`` started on each of ``recs`` as the fit started
    it.  A training record of a joint fit (same file content) starts from its own fitted start (fit.json
    ``per_record_start``); another record by the fit's start rule.  Several records with any own start: one start per
    record (`with_record_starts`); the new-record start ``(init, u0, memory)`` is the fit's rule, for the held-out
    record of the predictive check."""
    from ..identify._choose import COLD_FRACTION
    from ..models._hysteresis import hysteresis_of, thermal_of
    from .simulate import started_as_in_fit, training_record_start

    own = [training_record_start(doc, r) for r in recs]
    th, h = thermal_of(model), hysteresis_of(model)
    if th is None or all(o is None for o in own):
        return model, own, None
    rule = h.init if h is not None and getattr(h, "init", None) in getattr(h, "RULE_INITS", ()) else None
    new = (th.init, None if th.u0 is None else float(th.u0), rule)
    if len(recs) == 1:
        return started_as_in_fit(model, own[0]), own, new
    if getattr(model, "with_record_starts", None) is None:
        LOGGER.warning(f"note: a {type(model).__name__} holds one start for all records; each record starts by its rule")
        return model, [None] * len(recs), None
    floor = COLD_FRACTION * max(float(np.max(r.u)) for r in recs)  # a start at 0 V sits where the softplus is flat
    u0s = [float(o["u0_V"]) if o else max(th.start_voltage(r.u[0]), floor) for o, r in zip(own, recs)]
    rules = [o.get("memory") if o else None for o in own]
    inits = None if rule is None or all(x is None for x in rules) else [x or rule for x in rules]
    return model.with_record_starts(u0s, inits), own, new


def _hysteresis_input(post, rec, i):
    from ..models._range import effective_values

    x = effective_values(post.started_model(i), rec.u, rec.dt)
    return np.asarray(rec.u) if x is None else x


def _sampled_branches(post, recs, n_train) -> dict:
    """The hysteresis input's range and branches (`models._range.trained_branches_of`: a cascade's thermal state, else
    the input) over the sampled samples of every record, each record its own trajectory."""
    from ..models._range import trained_branches_of

    return trained_branches_of([(_hysteresis_input(post, r, i)[:n], None) for i, (r, n) in enumerate(zip(recs, n_train))])


#: A held-out sample is unconstrained when the 95 % band of the model output there is wider than this many noise SDs
#: (where the sampled data constrain the model it is well under one).
BAND_WARN = 4.0


def _where_untrained(post, target, i, held, sampled) -> str | None:
    """Why held-out samples may be unconstrained: how many drive the hysteresis outside the range the sampled samples
    cover, or along a branch they never walked (None when neither)."""
    from ..models._range import branch_check, range_check

    x = _hysteresis_input(post, target, i)[held]
    lo, hi = sampled["range"]
    out = range_check(x, [lo, hi], what="hysteresis input", column="state")
    branches = branch_check(x, sampled)
    what = []
    if "warning" in out:
        what.append(
            f"{out['n_beyond_tolerance']} lie outside the range [{lo:.4g}, {hi:.4g}] the sampled data cover (by more than "
            f"{out['tolerance']['fraction_of_span']:.0%} of its span)"
        )
    if "warning" in branches:
        what.append(f"{branches['n_untrained']} on branches the sampled data never walked")
    return " and ".join(what) or None


def _unit(rec) -> str | None:
    """The unit of ``rec``'s output column: the sidecar's, brackets (``displacement [mm]``) or a suffix (``_mm``)."""
    from ..report._reportdoc import unit_of

    return unit_of(rec.output_name, getattr(rec, "units", None))


def _unconstrained(post, target, i, mask, fq, sigma, sampled, y_span=None) -> str | None:
    """A warning when the model's own 95 % band on the held-out samples of ``target`` is wider than `BAND_WARN` noise
    SDs on more than a tenth of them: the sampled data do not constrain the model there, and the weights of operators
    they never moved come from their priors.  Measured (session 34): a joint fit's length-sensor records sampled on
    their first 75 %: the tails' bands 3 mm wide on a 1 mm stroke, with every operator column inside its sampled range.
    Widths are in the output's unit; where a band is wider than ``y_span`` (the span the output covers in the sampled
    data) the warning says the band means nothing there (a new-user trial read a 29 mm band on a 5 mm stroke as a
    wide uncertainty)."""
    held = ~np.asarray(mask, bool)
    if not held.any() or not sigma:
        return None
    width = fq[2] - fq[0]
    wide = held & (width > BAND_WARN * sigma)
    if wide.sum() <= 0.1 * held.sum():
        return None
    first = int(np.flatnonzero(wide)[0])
    why = _where_untrained(post, target, i, held, sampled)
    unit = _unit(target)
    u = f" {unit}" if unit else ""
    column = f" ({target.output_name})" if target.output_name else ""
    text = (
        f"{_record_file(target)}: on {int(wide.sum())} of {int(held.sum())} held-out samples (from {target.time[first]:.4g} s) "
        f"the 95 % band of the model output{column} is wider than {BAND_WARN:g} noise SDs (up to "
        f"{float(np.max(width[held])):.3g}{u}; noise SD {sigma:.3g}{u})"
    )
    text += ": the sampled data do not constrain the model there " + (
        f"({why})" if why else "(operator combinations the sampled data never excited)"
    )
    beyond = held & (width > y_span) if y_span else np.zeros_like(held)
    if beyond.any():
        first = int(np.flatnonzero(beyond)[0])
        text += (
            f"; on {int(beyond.sum())} of them (from {target.time[first]:.4g} s) the band is wider than the whole span the "
            f"output covers in the sampled data ({y_span:.3g}{u}): there it is meaningless (the model extrapolates), "
            "not a measure of uncertainty"
        )
    return text + "; sample on records that cover such drives, or hold out less"


#: `smafl sample` warns when the fit's own validation error exceeds this many noise SDs (fit.json
#: ``metrics.noise.validation_ratio``): the posterior is conditional on the fitted structure and cannot show what it
#: misses.  Measured (session 35, experiments/heldout_coverage.py, 24 independent records sampled on the fit's 70 %):
#: 9 held-out 95 % coverages fell below 0.90 (five of them at 0.00-0.11); the band warning above caught 3 of those 9, a
#: validation ratio above 2 caught 7, together 8.
STRUCTURE_WARN = 2.0


def _structure_warning(doc: dict) -> str | None:
    """A warning when the fit's validation error (a model fitted on part of its training data, scored on the rest) was
    above `STRUCTURE_WARN` noise SDs: the bands, conditional on that model structure, are then likely too narrow on
    new data."""
    ratio = ((doc.get("metrics") or {}).get("noise") or {}).get("validation_ratio")
    if not isinstance(ratio, (int, float)) or not np.isfinite(ratio) or ratio <= STRUCTURE_WARN:
        return None
    return (
        f"the fit's own validation error was {ratio:.3g}x the noise (fit.json metrics.noise.validation_ratio): the model "
        "misses something on data it was not fitted on, and this posterior, conditional on the fitted structure (hysteresis "
        "class, thresholds, tilts), cannot show it: expect its bands to be too narrow on new data (independent records "
        "like this one were covered by the 95 % bands on as little as 0-11 % of their held-out samples)"
    )


def _start_words(row, th) -> str | None:
    if th is None:
        return None
    if row is None:
        return f"the fit's start rule: {th.start_description()}"
    memory = f", {row['memory']} operator memory" if row.get("memory") else ""
    return f"its own start in the joint fit (record {row['record']}): {float(row['u0_V']):.4g} V{memory}"


def _save(fig, path):
    """Save atomically, then close: a library called in a loop must not pile up open pyplot figures."""
    import matplotlib.pyplot as plt

    from .._io import atomic_savefig

    try:
        atomic_savefig(fig, path)
    finally:
        plt.close(fig)


def sample_posterior(
    record: PathLike | Record | Sequence[PathLike | Record],
    fit: PathLike | Any,
    *,
    out: PathLike,
    heldout: PathLike | Record | Sequence[PathLike | Record] | None = None,
    steps: int = 3000,
    walkers: int | None = None,
    burn: int | None = None,
    linear: str = "auto",
    noise: str = "gaussian",
    nu: float = 4.0,
    priors: PathLike | Mapping[str, Prior] | None = None,
    gain_scale: float | None = None,
    holdout_fraction: float = 0.25,
    input: str | None = None,
    output: str | None = None,
    time: str | None = None,
    resample: float | str | None = None,
    window: tuple[float | None, float | None] | None = None,
    draws: int = 200,
    seed: int = 0,
    restart: bool = False,
    progress: bool = True,
    option_names: Mapping[str, str] | None = None,
    on_step: Callable[[int], Any] | None = None,
) -> SamplingResult:
    """Sample the posterior of ``fit``'s model conditioned on ``record``; write chain, summary and figures to ``out``.

    ``record`` / ``heldout``: a CSV path (a folder or glob: its files), a `Record`, or a sequence of them (the held-out
    records, run as new records, only enter the predictive check; default the last ``holdout_fraction`` of each
    record).  Several records: one model conditioned on all, each record run from its own start (a training record of
    a joint fit, matched by content: its fitted start, fit.json ``per_record_start``; another: the fit's start rule);
    the predictive figures get one panel per record, ``predictive.csv`` a ``record`` column.  ``fit``: a fit.json or
    model file path (its data columns and sample time are the defaults), or a model object.  ``time``: the CSVs'
    time column (default ``time_s``, else one named like a time; `smafl_jax.data.load_record`).  ``resample``: the CSVs'
    irregular stamps on a uniform grid of that many seconds ("auto": the median step; the samples interpolated across
    gaps are simulated through and left out of the likelihood and the coverage); ``window``: ``(start, end)`` seconds
    of each record to condition on (None ends open).
    ``linear``: ``"auto"`` (marginalise the hysteresis weights when the output is linear in them and
    the noise is Gaussian, profile them for Student-t noise, else sample them), ``"sample"``,
    ``"marginalise"`` or ``"profile"``.  ``priors``: a JSON file or ``{name: Prior}``.  Rerunning
    with the same settings extends the chain in ``out/chain.h5``; a chain of other settings is
    refused (`UserInputError`) unless ``restart``.  ``progress``: emcee's progress bar on stderr.
    ``option_names``: how error messages name the settings (the command line passes its flags).  ``on_step(k)``:
    called with the number of steps saved in ``out/chain.h5``, before sampling and after each step (`run_sampler`).
    """
    from .._io import atomic_write_csv, atomic_write_json, atomic_write_text, prepare_out_dir
    from ..bayes import _bayes as B
    from ..report._plots_bayes import corner_figure, panels_figure, predictive_loop_figure, predictive_time_figure, trace_figure
    from ..report._reportdoc import unit_of

    o = {**_OPTION_NAMES, **(option_names or {})}
    if steps < 10:
        raise UserInputError(f"{o['steps']} must be >= 10, got {steps}")
    if not 0.0 <= holdout_fraction < 0.9:
        raise UserInputError(f"{o['holdout_fraction']} must be in [0, 0.9), got {holdout_fraction}")
    if draws < 2:
        raise UserInputError(f"{o['draws']} must be >= 2, got {draws}")
    if burn is not None and not 0 <= burn < steps:
        raise UserInputError(f"{o['burn']} must be in [0, {o['steps']}) = [0, {steps}), got {burn}")
    if walkers is not None and walkers < 2:
        raise UserInputError(f"{o['walkers']} must be >= 2, got {walkers}")
    if gain_scale is not None and not (np.isfinite(gain_scale) and gain_scale > 0):
        raise UserInputError(f"{o['gain_scale']} must be > 0, got {gain_scale}")
    if not (np.isfinite(nu) and nu > 0):
        raise UserInputError(f"{o['nu']} must be > 0, got {nu}")
    if linear != "auto" and linear not in B.LINEAR_MODES:
        raise UserInputError(f"{o['linear']} must be 'auto' or one of {B.LINEAR_MODES}, got {linear!r}")

    from ..data._data import Record
    from ..models._hysteresis import thermal_of

    given = list(record) if isinstance(record, (list, tuple)) else [record]
    if any(isinstance(x, Record) for x in given) and (input or output or time):
        raise UserInputError("input / output / time name columns of a CSV; a Record given as the data has its columns already")
    model, doc, fit_sha, fit_label = _load_fit(fit)
    B.check_model_supported(model, where=fit_label or "fit")
    info = doc.get("data", {}) if isinstance(doc.get("data"), dict) else {}
    recs = _load_records(
        record,
        input=input or info.get("input_column"),
        output=output or info.get("output_column"),
        time=time,
        resample=resample,
        window=window,
    )
    rec = recs[0]
    several = len(recs) > 1
    for r in recs:
        if r.y is None:
            raise UserInputError(f"{r.path or r.name}: no output column to condition on")
    fit_dt = info.get("sample_time_s")
    for r in recs:
        if fit_dt and not np.isclose(fit_dt, r.dt, rtol=0.02):
            LOGGER.warning(f"note: the model was fitted at dt={fit_dt:g} s and {r.path or r.name} has dt={r.dt:g} s")
    if heldout is not None:
        held = _load_records(heldout, input=rec.input_name, output=rec.output_name, time=time, resample=resample)
        n_train = [len(r) for r in recs]
    else:
        held = []
        n_train = [len(r) - int(round(holdout_fraction * len(r))) for r in recs]
        short = [(r, n) for r, n in zip(recs, n_train) if n < 10]
        if short:
            r, n = short[0]
            raise UserInputError(f"{r.path or r.name}: only {n} samples left for sampling after holding out the tail")
    if linear == "auto":
        linear = "marginalise" if "marginalise" in B.linear_modes(model) else "sample"
        if linear == "marginalise" and noise != "gaussian":
            linear = "profile"
    if isinstance(priors, (str, os.PathLike)):
        priors = B.load_priors(priors)
    th = thermal_of(model)
    model, own_starts, new_start = _starts(model, doc, recs)
    post = B.Posterior(
        model,
        [(r.u[:n], r.y[:n], r.dt) for r, n in zip(recs, n_train)],
        # samples a resampling interpolated across gaps are simulated through but not in the likelihood
        mask=[r.measured[:n] for r, n in zip(recs, n_train)] if not all(r.measured.all() for r in recs) else None,
        noise=noise,
        nu=nu,
        priors=priors,
        linear=linear,
        gain_scale=gain_scale,
        new_record_start=new_start,
    )
    n_walkers = B.resolve_walkers(post.ndim, walkers)  # checked before anything is written

    out = prepare_out_dir(out)
    chain_path = out / "chain.h5"
    settings = {
        # one record: the keys of earlier versions, so that their chains resume
        "data_sha256": [r.sha256 for r in recs] if several else rec.sha256,
        "fit_sha256": fit_sha,
        "n_train": n_train if several else n_train[0],
        "linear": linear,
        "noise": noise,
        "nu": nu,
        "priors": {k: v.to_dict() for k, v in post.priors.items()},
        "gain_scale": post.gain_scale,
        "walkers": walkers,
        "seed": seed,
        "names": post.names,
    }
    run_json = out / "run.json"
    resume = chain_path.exists() and not restart
    if resume:
        try:
            old = json.loads(run_json.read_text())
        except (OSError, json.JSONDecodeError):
            old = None
        if old != json.loads(json.dumps(settings)):
            raise UserInputError(
                f"{chain_path} belongs to a run with other data or settings (see {run_json}); "
                f"pass {o['restart']} to discard it or choose another {o['out']}"
            )
    atomic_write_json(run_json, settings)
    LOGGER.info(
        f"sampling {post.ndim} parameters ({', '.join(post.names[:6])}{' ...' if post.ndim > 6 else ''}); "
        f"gains: {linear}; noise: {noise}" + (f"; {len(recs)} records, each from its own start" if several else "")
    )
    run = B.run_sampler(
        post, steps, n_walkers=n_walkers, path=chain_path, seed=seed, resume=resume, progress=progress, on_step=on_step
    )

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", B.ChainTooShortWarning)  # reported in summary["warnings"]
        summary = B.summarize(post, run, burn)
    structure = _structure_warning(doc)
    if structure:
        summary["warnings"].append(structure)
    rows = [
        {
            "file": _record_file(r),
            "sha256": r.sha256,
            "n_train": n,
            "sample_time_s": r.dt,
            "heldout": None if heldout is not None else (f"last {len(r) - n} samples" if n < len(r) else None),
            "start": _start_words(row, th),
            "processing": list(r.processing),
            # interpolated across resampling gaps: simulated through, not in the likelihood
            "n_train_interpolated_left_out": int(np.sum(~r.measured[:n])),
        }
        for r, n, row in zip(recs, n_train, own_starts)
    ]
    if several:
        summary["data"] = {
            "files": [row["file"] for row in rows],
            "input_column": rec.input_name,
            "output_column": rec.output_name,
            "records": rows,
            "heldout": [_record_file(r) for r in held] if held else f"last {holdout_fraction:g} of each record",
        }
    else:
        summary["data"] = {
            "file": rows[0]["file"],
            "sha256": rec.sha256,
            "input_column": rec.input_name,
            "output_column": rec.output_name,
            "n_train": n_train[0],
            "sample_time_s": rec.dt,
            "heldout": ", ".join(_record_file(r) for r in held) if held else rows[0]["heldout"],
            "processing": rows[0]["processing"],
            "n_train_interpolated_left_out": rows[0]["n_train_interpolated_left_out"],
        }
        if rows[0]["start"] and own_starts[0] is not None:
            summary["data"]["start"] = rows[0]["start"]
    summary["fit"] = fit_label

    # -- figures and tables ------------------------------------------------
    burn = summary["burn"]
    flat = run.chain[burn:].reshape(-1, post.ndim)
    rng = np.random.default_rng(seed + 1)
    idx = rng.choice(flat.shape[0], size=min(draws, flat.shape[0]), replace=False)
    phys_flat = post.physical(flat)
    y_unit = unit_of(rec.output_name, getattr(rec, "units", None))
    _save(corner_figure(phys_flat, post.names, output_unit=y_unit), out / "corner.png")
    chain_phys = post.physical(run.chain.reshape(-1, post.ndim)).reshape(run.chain.shape)
    _save(trace_figure(chain_phys, post.names, burn, output_unit=y_unit), out / "trace.png")
    # the predictive check: each given held-out record as a new record, else each record's held-out tail
    targets = (
        [(r, None, np.zeros(len(r), bool)) for r in held]
        if held
        else [(r, i, np.arange(len(r)) < n) for i, (r, n) in enumerate(zip(recs, n_train))]
    )
    ylabel = f"{rec.output_name}"
    tfig, taxes = panels_figure(len(targets), width=9, height=3.2) if len(targets) > 1 else (None, [None])
    lfig, laxes = (
        panels_figure(len(targets), width=5, height=4, columns=min(len(targets), 3)) if len(targets) > 1 else (None, [None])
    )
    table, covers, inside = {}, {}, [0, 0]
    sampled = _sampled_branches(post, recs, n_train)
    y_sampled = np.concatenate([r.y[:n] for r, n in zip(recs, n_train)])
    y_span = float(np.nanmax(y_sampled) - np.nanmin(y_sampled))  # blank measured cells are NaN
    sigma = (summary["parameters"].get("noise.sigma") or {}).get("mean")
    for k, (target, i, mask) in enumerate(targets):
        f, yrep = post.predict(flat[idx], target.u, target.dt, rng, record=i)
        title = _record_file(target) if len(targets) > 1 else None
        fig, cover = predictive_time_figure(
            target.time, target.y, f, yrep, mask, ylabel=ylabel, ax=taxes[k % len(taxes)], title=title
        )
        if tfig is None:
            _save(fig, out / "predictive_time.png")
        fig = predictive_loop_figure(
            target.u, target.y, f, mask, xlabel=target.input_name, ylabel=ylabel, ax=laxes[k % len(laxes)], title=title
        )
        if lfig is None:
            _save(fig, out / "predictive_loop.png")
        fq = np.quantile(f, [0.025, 0.5, 0.975], axis=0)
        yq = np.quantile(yrep, [0.025, 0.975], axis=0)
        loose = _unconstrained(post, target, i, mask, fq, sigma, sampled, y_span)
        if loose:
            summary["warnings"].append(loose)
        held_part = ~mask & target.measured  # interpolated samples are no measurements to cover
        n_in = int(np.sum((target.y >= yq[0]) & (target.y <= yq[1]) & held_part))
        covers[_record_file(target)] = n_in / int(held_part.sum()) if held_part.any() else cover
        inside[0] += n_in
        inside[1] += int(held_part.sum())
        # the CSV is numeric: the record column is the index into summary.json data.predictive_records
        part = {"record": np.full(len(target), float(k))} if len(targets) > 1 else {}
        part.update(
            {
                "time_s": target.time,
                target.input_name: target.u,
                target.output_name: target.y,
                "heldout": held_part.astype(float),
                "median": fq[1],
                "model_q025": fq[0],
                "model_q975": fq[2],
                "pred_q025": yq[0],
                "pred_q975": yq[1],
            }
        )
        for key, col in part.items():
            table.setdefault(key, []).append(np.asarray(col))
    if tfig is not None:
        _save(tfig, out / "predictive_time.png")
        _save(lfig, out / "predictive_loop.png")
    atomic_write_csv(out / "predictive.csv", {key: np.concatenate(cols) for key, cols in table.items()})
    # pooled over every held-out sample; per record as well when there are several
    summary["heldout_coverage_95"] = inside[0] / inside[1] if inside[1] else None
    if len(targets) > 1:
        summary["heldout_coverage_95_per_record"] = covers
        summary["data"]["predictive_records"] = list(covers)
    atomic_write_json(out / "summary.json", summary)
    lines = ["name,mean,sd,q025,q975,ess,autocorr_time"]
    for name, s in summary["parameters"].items():
        lines.append(
            f"{name},{s['mean']:.8g},{s['sd']:.8g},{s['q025']:.8g},{s['q975']:.8g},{s['ess']:.1f},{s['autocorr_time']:.2f}"
        )
    atomic_write_text(out / "parameters.csv", "\n".join(lines) + "\n")
    return SamplingResult(summary=summary, out=out, files={name: out / name for name in FILES}, posterior=post, run=run)
