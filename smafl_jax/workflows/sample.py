"""Posterior sampling of a fitted model as one library call (the workflow behind ``smafl sample``).

`sample_posterior` loads the record(s) and the fit, builds the `Posterior`
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
from collections.abc import Mapping
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


def _label(source) -> str:
    """How messages name a record or fit given as a path or as an object."""
    if isinstance(source, (str, os.PathLike)):
        return str(source)
    path = getattr(source, "path", None)
    return str(path) if path else getattr(source, "name", type(source).__name__)


def _file_name(source) -> str:
    if isinstance(source, (str, os.PathLike)):
        return Path(source).name
    path = getattr(source, "path", None)
    return Path(path).name if path else getattr(source, "name", "record")


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


def _load(record, *, input=None, output=None):
    from ..data._data import Record, load_record

    if isinstance(record, Record):
        return record  # its columns are chosen already
    if isinstance(record, (str, os.PathLike)):
        return load_record(record, input=input, output=output)
    raise UserInputError(f"expected a CSV path or a Record, got a {type(record).__name__}")


def _save(fig, path):
    """Save atomically, then close: a library called in a loop must not pile up open pyplot figures."""
    import matplotlib.pyplot as plt

    from .._io import atomic_savefig

    try:
        atomic_savefig(fig, path)
    finally:
        plt.close(fig)


def sample_posterior(
    record: PathLike | Record,
    fit: PathLike | Any,
    *,
    out: PathLike,
    heldout: PathLike | Record | None = None,
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
    draws: int = 200,
    seed: int = 0,
    restart: bool = False,
    progress: bool = True,
    option_names: Mapping[str, str] | None = None,
) -> SamplingResult:
    """Sample the posterior of ``fit``'s model conditioned on ``record``; write chain, summary and figures to ``out``.

    ``record`` / ``heldout``: a CSV path or a `Record` (the held-out record, default the last
    ``holdout_fraction`` of ``record``, only enters the predictive check).  ``fit``: a fit.json or
    model file path (its data columns and sample time are the defaults), or a model object.
    ``linear``: ``"auto"`` (marginalise the hysteresis weights when the output is linear in them and
    the noise is Gaussian, profile them for Student-t noise, else sample them), ``"sample"``,
    ``"marginalise"`` or ``"profile"``.  ``priors``: a JSON file or ``{name: Prior}``.  Rerunning
    with the same settings extends the chain in ``out/chain.h5``; a chain of other settings is
    refused (`UserInputError`) unless ``restart``.  ``progress``: emcee's progress bar on stderr.
    ``option_names``: how error messages name the settings (the command line passes its flags).
    """
    from .._io import atomic_write_csv, atomic_write_json, atomic_write_text, prepare_out_dir
    from ..bayes import _bayes as B
    from ..report._plots_bayes import corner_figure, predictive_loop_figure, predictive_time_figure, trace_figure
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

    if isinstance(record, Record) and (input or output):
        raise UserInputError("input / output name columns of a CSV; a Record given as the data has its columns already")
    model, doc, fit_sha, fit_label = _load_fit(fit)
    B.check_model_supported(model, where=fit_label or "fit")
    info = doc.get("data", {}) if isinstance(doc.get("data"), dict) else {}
    rec = _load(record, input=input or info.get("input_column"), output=output or info.get("output_column"))
    data_label = _label(record)
    if rec.y is None:
        raise UserInputError(f"{data_label}: no output column to condition on")
    fit_dt = info.get("sample_time_s")
    if fit_dt and not np.isclose(fit_dt, rec.dt, rtol=0.02):
        LOGGER.warning(f"note: the model was fitted at dt={fit_dt:g} s and {data_label} has dt={rec.dt:g} s")
    if heldout is not None:
        held = _load(heldout, input=rec.input_name, output=rec.output_name)
        n_train = len(rec)
    else:
        held = None
        n_train = len(rec) - int(round(holdout_fraction * len(rec)))
        if n_train < 10:
            raise UserInputError(f"{data_label}: only {n_train} samples left for sampling after holding out the tail")
    if linear == "auto":
        linear = "marginalise" if "marginalise" in B.linear_modes(model) else "sample"
        if linear == "marginalise" and noise != "gaussian":
            linear = "profile"
    if isinstance(priors, (str, os.PathLike)):
        priors = B.load_priors(priors)
    post = B.Posterior(
        model,
        (rec.u[:n_train], rec.y[:n_train]),
        rec.dt,
        noise=noise,
        nu=nu,
        priors=priors,
        linear=linear,
        gain_scale=gain_scale,
    )
    n_walkers = B.resolve_walkers(post.ndim, walkers)  # checked before anything is written

    out = prepare_out_dir(out)
    chain_path = out / "chain.h5"
    settings = {
        "data_sha256": rec.sha256,
        "fit_sha256": fit_sha,
        "n_train": n_train,
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
        f"gains: {linear}; noise: {noise}"
    )
    run = B.run_sampler(post, steps, n_walkers=n_walkers, path=chain_path, seed=seed, resume=resume, progress=progress)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", B.ChainTooShortWarning)  # reported in summary["warnings"]
        summary = B.summarize(post, run, burn)
    summary["data"] = {
        "file": _file_name(record),
        "sha256": rec.sha256,
        "input_column": rec.input_name,
        "output_column": rec.output_name,
        "n_train": n_train,
        "sample_time_s": rec.dt,
        "heldout": _file_name(heldout)
        if heldout is not None
        else (f"last {len(rec) - n_train} samples" if n_train < len(rec) else None),
    }
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
    target = held if held is not None else rec
    f, yrep = post.predict(flat[idx], target.u, target.dt, rng)
    mask = np.zeros(len(target), bool) if held is not None else (np.arange(len(rec)) < n_train)
    ylabel = f"{target.output_name}"
    fig, cover = predictive_time_figure(target.time, target.y, f, yrep, mask, ylabel=ylabel)
    _save(fig, out / "predictive_time.png")
    _save(
        predictive_loop_figure(target.u, target.y, f, mask, xlabel=target.input_name, ylabel=ylabel), out / "predictive_loop.png"
    )
    fq = np.quantile(f, [0.025, 0.5, 0.975], axis=0)
    yq = np.quantile(yrep, [0.025, 0.975], axis=0)
    atomic_write_csv(
        out / "predictive.csv",
        {
            "time_s": target.time,
            target.input_name: target.u,
            target.output_name: target.y,
            "heldout": (~mask).astype(float),
            "median": fq[1],
            "model_q025": fq[0],
            "model_q975": fq[2],
            "pred_q025": yq[0],
            "pred_q975": yq[1],
        },
    )
    summary["heldout_coverage_95"] = cover
    atomic_write_json(out / "summary.json", summary)
    lines = ["name,mean,sd,q025,q975,ess,autocorr_time"]
    for name, s in summary["parameters"].items():
        lines.append(
            f"{name},{s['mean']:.8g},{s['sd']:.8g},{s['q025']:.8g},{s['q975']:.8g},{s['ess']:.1f},{s['autocorr_time']:.2f}"
        )
    atomic_write_text(out / "parameters.csv", "\n".join(lines) + "\n")
    return SamplingResult(summary=summary, out=out, files={name: out / name for name in FILES}, posterior=post, run=run)
