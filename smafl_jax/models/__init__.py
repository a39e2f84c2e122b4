"""Model classes (equinox PyTrees) and what every model needs.

The hysteresis protocol (`AbstractHysteresis`) and its models (`EUPI`, `Preisach`, `GaussianPreisach`, `PhaseFraction`), the Joule thermal lag
(`JouleThermal`), the paper's eq. (7) model (`JouleLag`), the `Cascade`, the play operators and the
models' evaluation-method rule, positivity constraints, initial-state rules, the jitted `simulate`
entry points, padded calls and trained-range checks.
"""

from ._cascade import SEES, Cascade
from ._constraints import POSITIVE_FLOOR, as_float_array, constrain, log_jacobian, parameter, positive, positive_mask, unconstrain
from ._eupi import EUPI, threshold_grid, tilt_grid
from ._hysteresis import (
    AbstractHysteresis,
    AbstractScaledShape,
    column_weight_scales,
    hysteresis_class,
    hysteresis_models,
    hysteresis_of,
    linear_field_columns,
    thermal_of,
)
from ._initial_state import INITIAL_STATE_RULES, estimate_initial_state, with_initial_state
from ._joule_lag import JouleLag
from ._median import MedianOfModels
from ._operators import (
    MODEL_METHODS,
    choose_model_method,
    consistent_initial_state,
    model_with_method,
    play,
    play_assoc,
    play_scan,
    play_step,
    play_weighted,
    resolve_method,
)
from ._padding import MIN_BUCKET, bucket_length, padded_call
from ._phase_fraction import PhaseFraction
from ._preisach import (
    EVERETT_INTERPOLANTS,
    LAM_GRID,
    N_LEVELS_GRID,
    Preisach,
    cv_fit_preisach,
    everett_weights,
    fit_everett,
    fit_preisach,
    forc_shaped,
    preisach_levels,
    relay_loop,
    solve_penalised,
    tikhonov_matrix,
)
from ._preisach_gauss import GaussianPreisach
from ._range import branch_check, effective_range, hysteresis_values, range_check, trained_branches, trained_branches_of
from ._simulate import compile_form, simulate, simulate_batch, user_form
from ._thermal import PAPER_K1, PAPER_K2, JouleThermal, effective_voltage, thermal_step

__all__ = [
    "AbstractHysteresis",
    "AbstractScaledShape",
    "GaussianPreisach",
    "PhaseFraction",
    "hysteresis_of",
    "thermal_of",
    "hysteresis_models",
    "hysteresis_class",
    "column_weight_scales",
    "EUPI",
    "threshold_grid",
    "tilt_grid",
    "Preisach",
    "preisach_levels",
    "tikhonov_matrix",
    "fit_preisach",
    "cv_fit_preisach",
    "relay_loop",
    "everett_weights",
    "fit_everett",
    "forc_shaped",
    "JouleThermal",
    "PAPER_K1",
    "PAPER_K2",
    "thermal_step",
    "effective_voltage",
    "JouleLag",
    "SEES",
    "Cascade",
    "MedianOfModels",
    "MODEL_METHODS",
    "choose_model_method",
    "resolve_method",
    "model_with_method",
    "play_step",
    "play",
    "play_scan",
    "play_assoc",
    "play_weighted",
    "consistent_initial_state",
    "positive",
    "parameter",
    "as_float_array",
    "constrain",
    "unconstrain",
    "log_jacobian",
    "positive_mask",
    "POSITIVE_FLOOR",
    "INITIAL_STATE_RULES",
    "with_initial_state",
    "estimate_initial_state",
    "simulate",
    "simulate_batch",
    "compile_form",
    "user_form",
    "bucket_length",
    "padded_call",
    # Documented helpers that tests and experiments use (issue 12: they import the sub-package API).
    "linear_field_columns",
    "MIN_BUCKET",
    "EVERETT_INTERPOLANTS",
    "LAM_GRID",
    "N_LEVELS_GRID",
    "solve_penalised",
    "range_check",
    "branch_check",
    "trained_branches",
    "trained_branches_of",
    "effective_range",
    "hysteresis_values",
]
