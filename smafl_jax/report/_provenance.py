"""Provenance of written results: the one `versions()` and the fit.json header (format, version, model, data).

Used by `smafl fit` (`_report_fit.fit_record`), the multi-record fit (`_multi_record`) and the diagnosis
files (`_report`), so that every fit.json-format file names its format, model and data the same way.
"""

from __future__ import annotations

import platform
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

__all__ = ["versions", "fit_header", "record_data", "PACKAGES"]

# distribution names; the keys of `versions()` use underscores ("smafl-jax" -> "smafl_jax")
PACKAGES = ("smafl-jax", "jax", "jaxlib", "equinox", "optimistix", "jaxopt", "numpy", "scipy")


def versions(extra: tuple[str, ...] = ()) -> dict:
    """Python and package versions (from the installed distributions' metadata; None when one is missing).

    ``extra``: further distributions to list (e.g. ``("emcee", "matplotlib")``).
    """
    out = {"python": platform.python_version()}
    for pkg in PACKAGES + tuple(p for p in extra if p not in PACKAGES):
        try:
            out[pkg.replace("-", "_")] = version(pkg)
        except PackageNotFoundError:
            out[pkg.replace("-", "_")] = None
    return out


def solver_entry(res, seconds: float, **extra) -> dict:
    """fit.json ``solver``: what the identification's `FitResult` says about the solve, the seconds, then ``extra``."""
    return {
        "name": res.solver,
        "loss": res.loss,
        "init_loss": res.init_loss,
        "n_steps": res.n_steps,
        "converged": res.converged,
        "message": res.message,
        "seconds": seconds,
        **extra,
    }


def fit_header(model) -> dict:
    """The first entries of a fit.json-format file: ``format``, ``version`` and the ``model``."""
    from .._io import FORMAT, VERSION, model_to_dict

    return {"format": FORMAT, "version": VERSION, "model": model_to_dict(model)}


def record_data(record) -> dict:
    """Data provenance of one record: file, path, sha256, columns, sample time, length and units."""
    return {
        "file": Path(record.path).name if record.path else None,
        "path": str(record.path) if record.path else None,
        "sha256": record.sha256,
        "input_column": record.input_name,
        "output_column": record.output_name,
        "sample_time_s": float(record.dt),
        "n_samples": len(record),
        "units": dict(record.units),
    }
