"""smafl-jax: differentiable system identification for hysteretic, thermally driven artificial muscles.

The public names are re-exported here from the sub-packages, one per concept: `models`, `identify`,
`bayes`, `control`, `diagnosis`, `report`, `paper`, `data`, `ops`, `effects`, `workflows`, `cli`
(see each one's docstring); the modules inside them are private.  Importing the package enables JAX's
64-bit mode (identification at float32 is not accurate enough).
"""

import os as _os
import sys as _sys
from importlib import import_module as _import_module

from ._errors import DataError, UserInputError


def _package_version() -> str:
    """The installed distribution's version; from a source tree that is not installed, pyproject.toml's."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("smafl-jax")
    except PackageNotFoundError:
        try:
            import tomllib

            with open(_os.path.join(_os.path.dirname(__file__), _os.pardir, "pyproject.toml"), "rb") as f:
                return str(tomllib.load(f)["project"]["version"])
        except (OSError, KeyError, ValueError):
            return "0.0.0+unknown"


__version__ = _package_version()

# The public names are imported on first use (PEP 562), so that `smafl --help` and `import smafl_jax`
# do not pay for importing JAX, SciPy and matplotlib.  x64 must hold before any array is made: if
# JAX is already imported it is switched now, otherwise JAX reads JAX_ENABLE_X64 when it is imported.
if "jax" in _sys.modules:
    from . import _config  # noqa: F401
else:
    _os.environ["JAX_ENABLE_X64"] = "True"

_LAZY = {
    "Cascade": "models._cascade",
    "MedianOfModels": "models._median",
    "POSITIVE_FLOOR": "models._constraints",
    "constrain": "models._constraints",
    "log_jacobian": "models._constraints",
    "parameter": "models._constraints",
    "positive": "models._constraints",
    "positive_mask": "models._constraints",
    "unconstrain": "models._constraints",
    "Record": "data._data",
    "file_sha256": "data._data",
    "load_record": "data._data",
    "EUPI": "models._eupi",
    "threshold_grid": "models._eupi",
    "tilt_grid": "models._eupi",
    "atomic_savefig": "_io",
    "atomic_write_csv": "_io",
    "atomic_write_json": "_io",
    "atomic_write_text": "_io",
    "load_model": "_io",
    "load_model_file": "_io",
    "model_from_dict": "_io",
    "model_to_dict": "_io",
    "prepare_out_dir": "_io",
    "register_model": "_io",
    "save_model": "_io",
    "to_jsonable": "_io",
    "e_mean": "identify._metrics",
    "error_ratio": "identify._metrics",
    "max_abs_error": "identify._metrics",
    "mean_abs_error": "identify._metrics",
    "metrics": "identify._metrics",
    "noise_floor": "identify._metrics",
    "search_memory": "identify._memory_search",
    "rmse": "identify._metrics",
    "consistent_initial_state": "models._operators",
    "play": "models._operators",
    "play_assoc": "models._operators",
    "play_scan": "models._operators",
    "play_step": "models._operators",
    "play_weighted": "models._operators",
    "simulate": "models._simulate",
    "simulate_batch": "models._simulate",
    "with_initial_state": "models._initial_state",
    "AbstractHysteresis": "models._hysteresis",
    "hysteresis_of": "models._hysteresis",
    "thermal_of": "models._hysteresis",
    "estimate_initial_state": "models._initial_state",
    "PAPER_K1": "models._thermal",
    "PAPER_K2": "models._thermal",
    "JouleThermal": "models._thermal",
    "effective_voltage": "models._thermal",
    "thermal_step": "models._thermal",
    "ChainTooShortWarning": "bayes._bayes",
    "Posterior": "bayes._bayes",
    "Prior": "bayes._bayes",
    "SampleRun": "bayes._bayes",
    "default_priors": "bayes._bayes",
    "diagnostics": "bayes._bayes",
    "load_priors": "bayes._bayes",
    "load_run": "bayes._bayes",
    "run_sampler": "bayes._bayes",
    "summarize": "bayes._bayes",
    "SamplingResult": "workflows.sample",
    "sample_posterior": "workflows.sample",
    "ControlResult": "workflows.control",
    "run_control": "workflows.control",
    "ControlSweepResult": "workflows.sweep",
    "run_sweep": "workflows.sweep",
    "SimulationResult": "workflows.simulate",
    "simulate_record": "workflows.simulate",
    "PID": "control._control",
    "ClosedLoop": "control._control",
    "IICompensator": "control._control",
    "closed_loop_metrics": "control._control",
    "simulate_closed_loop": "control._control",
    "sine_reference": "control._control",
    "step_reference": "control._control",
    "diagnose": "diagnosis._diagnose",
    "diagnose_records": "diagnosis._several",
    "RecordsDiagnosis": "diagnosis._several",
    "Diagnosis": "diagnosis._result",
    "EFFECT_NAMES": "effects",
    "EFFECTS": "effects",
    "ExtendedModel": "effects",
    "SOLVERS": "identify._fit",
    "StallStop": "identify._stall",
    "FitResult": "identify._fit",
    "as_fit_data": "identify._fit",
    "default_trainable": "identify._fit",
    "fit": "identify._fit",
    "fit_many": "identify._fit",
    "init_linear": "identify._fit",
    "init_profile": "identify._fit",
    "fit_records": "identify._multi_record",
    "JouleLag": "models._joule_lag",
    "Preisach": "models._preisach",
    "GaussianPreisach": "models._preisach_gauss",
    "PhaseFraction": "models._phase_fraction",
    "split_masks": "identify._split",
    "SweepResult": "control._sweep",
    "stack_models": "control._sweep",
    "sweep": "control._sweep",
    "initialize_from_env": "control._distributed",
    "choose_model_method": "models._operators",
    "model_with_method": "models._operators",
    "Recalibrated": "identify._recalibrate",
    "recalibrate": "identify._recalibrate",
}


def __getattr__(name):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from . import _config  # noqa: F401  (x64 before the first array)

    value = getattr(_import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))


def _load_all():
    """Import every public module (registers all model classes for JSON loading)."""
    from . import _config  # noqa: F401

    for module in sorted(set(_LAZY.values())):
        _import_module(f".{module}", __name__)


__all__ = [
    "as_fit_data",
    "atomic_savefig",
    "atomic_write_csv",
    "atomic_write_json",
    "atomic_write_text",
    "Cascade",
    "MedianOfModels",
    "ChainTooShortWarning",
    "closed_loop_metrics",
    "ClosedLoop",
    "consistent_initial_state",
    "constrain",
    "DataError",
    "default_priors",
    "default_trainable",
    "diagnose",
    "diagnose_records",
    "Diagnosis",
    "diagnostics",
    "RecordsDiagnosis",
    "e_mean",
    "EFFECT_NAMES",
    "effective_voltage",
    "EFFECTS",
    "error_ratio",
    "EUPI",
    "ExtendedModel",
    "file_sha256",
    "fit",
    "fit_many",
    "fit_records",
    "FitResult",
    "IICompensator",
    "init_linear",
    "init_profile",
    "JouleLag",
    "JouleThermal",
    "load_model",
    "load_model_file",
    "load_priors",
    "load_record",
    "load_run",
    "log_jacobian",
    "max_abs_error",
    "mean_abs_error",
    "metrics",
    "model_from_dict",
    "noise_floor",
    "search_memory",
    "model_to_dict",
    "PAPER_K1",
    "PAPER_K2",
    "parameter",
    "PID",
    "play",
    "play_assoc",
    "play_scan",
    "play_step",
    "play_weighted",
    "positive",
    "POSITIVE_FLOOR",
    "positive_mask",
    "Posterior",
    "Preisach",
    "GaussianPreisach",
    "PhaseFraction",
    "prepare_out_dir",
    "Prior",
    "Recalibrated",
    "recalibrate",
    "Record",
    "register_model",
    "rmse",
    "run_sampler",
    "sample_posterior",
    "SamplingResult",
    "ControlResult",
    "run_control",
    "ControlSweepResult",
    "run_sweep",
    "SimulationResult",
    "simulate_record",
    "SampleRun",
    "save_model",
    "simulate",
    "with_initial_state",
    "AbstractHysteresis",
    "hysteresis_of",
    "thermal_of",
    "estimate_initial_state",
    "simulate_batch",
    "simulate_closed_loop",
    "sine_reference",
    "SOLVERS",
    "StallStop",
    "split_masks",
    "stack_models",
    "step_reference",
    "summarize",
    "sweep",
    "initialize_from_env",
    "choose_model_method",
    "model_with_method",
    "SweepResult",
    "thermal_step",
    "threshold_grid",
    "tilt_grid",
    "to_jsonable",
    "unconstrain",
    "UserInputError",
]
