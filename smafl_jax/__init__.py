"""smafl-jax: differentiable system identification for hysteretic, thermally driven artificial muscles.

Models (PyTrees), operators, data loading and metrics are re-exported here;
the modules behind them are private.  Importing the package enables JAX's
64-bit mode (identification at float32 is not accurate enough).
"""

from . import _config  # noqa: F401  (enables x64 first)
from ._cascade import Cascade
from ._constraints import POSITIVE_FLOOR, constrain, log_jacobian, parameter, positive, positive_mask, unconstrain
from ._data import Record, file_sha256, load_record
from ._errors import DataError, UserInputError
from ._eupi import EUPI, threshold_grid, tilt_grid
from ._io import (
    atomic_savefig,
    atomic_write_csv,
    atomic_write_json,
    atomic_write_text,
    load_model,
    load_model_file,
    model_from_dict,
    model_to_dict,
    prepare_out_dir,
    register_model,
    save_model,
    to_jsonable,
)
from ._metrics import e_mean, error_ratio, max_abs_error, mean_abs_error, metrics, rmse
from ._operators import consistent_initial_state, play, play_assoc, play_scan, play_step, play_weighted
from ._simulate import simulate, simulate_batch
from ._thermal import PAPER_K1, PAPER_K2, JouleThermal, effective_voltage, thermal_step

__version__ = "0.1.0"

# identification
# uncertainty
from ._bayes import (
    ChainTooShortWarning,
    Posterior,
    Prior,
    SampleRun,
    default_priors,
    diagnostics,
    load_priors,
    load_run,
    run_sampler,
    summarize,
)

# control
from ._control import PID, ClosedLoop, IICompensator, closed_loop_metrics, simulate_closed_loop, sine_reference, step_reference
from ._diagnose import diagnose

# residual diagnosis and effects
from ._effects import EFFECT_NAMES, EFFECTS, ExtendedModel
from ._fit import SOLVERS, FitResult, as_fit_data, default_trainable, fit, fit_many, init_linear, init_profile
from ._joule_lag import JouleLag
from ._preisach import Preisach
from ._split import split_masks
from ._sweep import SweepResult, stack_models, sweep

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
    "Record",
    "register_model",
    "rmse",
    "run_sampler",
    "SampleRun",
    "save_model",
    "simulate",
    "simulate_batch",
    "simulate_closed_loop",
    "sine_reference",
    "SOLVERS",
    "split_masks",
    "stack_models",
    "step_reference",
    "summarize",
    "sweep",
    "SweepResult",
    "thermal_step",
    "threshold_grid",
    "tilt_grid",
    "to_jsonable",
    "unconstrain",
    "UserInputError",
]
