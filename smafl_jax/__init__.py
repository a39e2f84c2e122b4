"""smafl-jax: differentiable system identification for hysteretic, thermally driven artificial muscles.

Models (PyTrees), operators, data loading and metrics are re-exported here;
the modules behind them are private.  Importing the package enables JAX's
64-bit mode (identification at float32 is not accurate enough).
"""

import os as _os
import sys as _sys
from importlib import import_module as _import_module

from ._errors import DataError, UserInputError

__version__ = "0.1.0"

# The public names are imported on first use (PEP 562), so that `smafl --help` and `import smafl_jax`
# do not pay for importing JAX, SciPy and matplotlib.  x64 must hold before any array is made: if
# JAX is already imported it is switched now, otherwise JAX reads JAX_ENABLE_X64 when it is imported.
if "jax" in _sys.modules:
    from . import _config  # noqa: F401
else:
    _os.environ["JAX_ENABLE_X64"] = "True"

_LAZY = {
    "Cascade": "_cascade",
    "POSITIVE_FLOOR": "_constraints",
    "constrain": "_constraints",
    "log_jacobian": "_constraints",
    "parameter": "_constraints",
    "positive": "_constraints",
    "positive_mask": "_constraints",
    "unconstrain": "_constraints",
    "Record": "_data",
    "file_sha256": "_data",
    "load_record": "_data",
    "EUPI": "_eupi",
    "threshold_grid": "_eupi",
    "tilt_grid": "_eupi",
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
    "e_mean": "_metrics",
    "error_ratio": "_metrics",
    "max_abs_error": "_metrics",
    "mean_abs_error": "_metrics",
    "metrics": "_metrics",
    "rmse": "_metrics",
    "consistent_initial_state": "_operators",
    "play": "_operators",
    "play_assoc": "_operators",
    "play_scan": "_operators",
    "play_step": "_operators",
    "play_weighted": "_operators",
    "simulate": "_simulate",
    "simulate_batch": "_simulate",
    "with_initial_state": "_initial_state",
    "AbstractHysteresis": "_hysteresis",
    "hysteresis_of": "_hysteresis",
    "estimate_initial_state": "_initial_state",
    "PAPER_K1": "_thermal",
    "PAPER_K2": "_thermal",
    "JouleThermal": "_thermal",
    "effective_voltage": "_thermal",
    "thermal_step": "_thermal",
    "ChainTooShortWarning": "_bayes",
    "Posterior": "_bayes",
    "Prior": "_bayes",
    "SampleRun": "_bayes",
    "default_priors": "_bayes",
    "diagnostics": "_bayes",
    "load_priors": "_bayes",
    "load_run": "_bayes",
    "run_sampler": "_bayes",
    "summarize": "_bayes",
    "SamplingResult": "workflows.sample",
    "sample_posterior": "workflows.sample",
    "ControlResult": "workflows.control",
    "run_control": "workflows.control",
    "ControlSweepResult": "workflows.sweep",
    "run_sweep": "workflows.sweep",
    "SimulationResult": "workflows.simulate",
    "simulate_record": "workflows.simulate",
    "PID": "_control",
    "ClosedLoop": "_control",
    "IICompensator": "_control",
    "closed_loop_metrics": "_control",
    "simulate_closed_loop": "_control",
    "sine_reference": "_control",
    "step_reference": "_control",
    "diagnose": "_diagnose",
    "EFFECT_NAMES": "_effects",
    "EFFECTS": "_effects",
    "ExtendedModel": "_effects",
    "SOLVERS": "_fit",
    "FitResult": "_fit",
    "as_fit_data": "_fit",
    "default_trainable": "_fit",
    "fit": "_fit",
    "fit_many": "_fit",
    "init_linear": "_fit",
    "init_profile": "_fit",
    "fit_records": "_multi_record",
    "JouleLag": "_joule_lag",
    "Preisach": "_preisach",
    "split_masks": "_split",
    "SweepResult": "_sweep",
    "stack_models": "_sweep",
    "sweep": "_sweep",
    "initialize_from_env": "_distributed",
    "choose_model_method": "_operators",
    "model_with_method": "_operators",
    "Recalibrated": "_recalibrate",
    "recalibrate": "_recalibrate",
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
    "ChainTooShortWarning",
    "closed_loop_metrics",
    "ClosedLoop",
    "consistent_initial_state",
    "constrain",
    "DataError",
    "default_priors",
    "default_trainable",
    "diagnose",
    "diagnostics",
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
    "estimate_initial_state",
    "simulate_batch",
    "simulate_closed_loop",
    "sine_reference",
    "SOLVERS",
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
