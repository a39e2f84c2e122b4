"""Identification: fitting a model to measured records (issue 12).

The fit itself (profiled initialiser + joint refinement), the automatic start (structure, output
orientation, thermal start), the linear solver shared by fit, diagnose and the Preisach cross-validation,
the variable-projection search shared by the fit's k1 profile, the thermal-start search and the diagnosis
(`varpro`), train/validation splits, the decimated view of long records, several records at once,
recalibration on a new run, the baselines set beside every fit and the error metrics.
"""

from __future__ import annotations

from ._baselines import (
    BASELINES,
    LAG_GRID,
    LagPoly,
    StaticPoly,
    baselines_doc,
    baselines_markdown,
    compare_sentences,
    fit_baselines,
    fit_lag_poly,
    fit_static_poly,
    is_voltage,
    score,
    tau_grid,
)
from ._choose import (
    COLD_FRACTION,
    SPARSE_SUFFIX,
    START_FRACTIONS,
    auto_candidates,
    auto_structure,
    candidate_model,
    fitted_memory_start,
    refine_thermal_start,
    screen_start,
    shared_screening,
)
from ._decimate import decimate_mask, decimate_record, fit_stride
from ._fit import SOLVERS, FitResult, as_fit_data, default_trainable, fit, fit_many, init_linear, init_profile
from ._memory_search import MEMORY_FRACTIONS, MEMORY_SWEEPS, search_memory
from ._metrics import e_mean, error_ratio, max_abs_error, mean_abs_error, metrics, noise_floor, rmse
from ._multi_record import (
    START_MISMATCH,
    add_record_extras,
    data_checks_doc,
    data_checks_markdown,
    fit_records,
    loro_sentences,
    start_mismatch,
    write_records_outputs,
)
from ._recalibrate import CALIBRATION_PARAMETERS, Recalibrated, after_segment_metrics, recalibrate, segment_indices
from ._split import SPLITS, split_masks
from ._stall import STALL_MIN_GAIN, STALL_WINDOW, StallStop
from .linear import METHODS, LinearSolution, column_scale, solve, solve_gram
from .varpro import Bounded, LinearProjection, NelderMead, Profiled, Search, search

__all__ = [
    "METHODS",
    "LinearSolution",
    "column_scale",
    "solve",
    "solve_gram",
    "Profiled",
    "LinearProjection",
    "Bounded",
    "NelderMead",
    "Search",
    "search",
    "FitResult",
    "fit",
    "fit_many",
    "init_linear",
    "init_profile",
    "default_trainable",
    "as_fit_data",
    "SOLVERS",
    "StallStop",
    "START_MISMATCH",
    "start_mismatch",
    "STALL_WINDOW",
    "STALL_MIN_GAIN",
    "auto_candidates",
    "auto_structure",
    "candidate_model",
    "SPARSE_SUFFIX",
    "screen_start",
    "shared_screening",
    "refine_thermal_start",
    "fitted_memory_start",
    "search_memory",
    "MEMORY_FRACTIONS",
    "MEMORY_SWEEPS",
    "COLD_FRACTION",
    "START_FRACTIONS",
    "split_masks",
    "SPLITS",
    "fit_records",
    "write_records_outputs",
    "data_checks_doc",
    "data_checks_markdown",
    "add_record_extras",
    "Recalibrated",
    "recalibrate",
    "segment_indices",
    "after_segment_metrics",
    "CALIBRATION_PARAMETERS",
    "BASELINES",
    "LAG_GRID",
    "StaticPoly",
    "LagPoly",
    "fit_static_poly",
    "fit_lag_poly",
    "fit_baselines",
    "score",
    "compare_sentences",
    "baselines_markdown",
    "is_voltage",
    "tau_grid",
    "baselines_doc",
    "error_ratio",
    "e_mean",
    "rmse",
    "max_abs_error",
    "mean_abs_error",
    "metrics",
    "noise_floor",
    # Documented helpers that tests and experiments use (issue 12: they import the sub-package API).
    "decimate_mask",
    "decimate_record",
    "fit_stride",
    "loro_sentences",
]
