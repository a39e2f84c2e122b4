"""Residual diagnosis (`smafl diagnose`): the base model, residual statistics, attribution of the
catalogue effects and the generic, labelled correction when the residual stays unexplained.

(Named ``diagnosis`` because ``smafl_jax.diagnose`` is the public function.)
"""

from ._diagnose import Segment, Split, choose_base, diagnose, effect_evidence, fit_extended, make_split
from ._residuals import (
    autocorrelation,
    candidate_signals,
    cross_correlation,
    effective_n,
    ljung_box,
    signal_correlations,
    whiteness_report,
)
from ._result import Diagnosis, ResidualArrays
from ._unexplained import (
    LABEL,
    apply_correction,
    cv_ridge,
    describe,
    expand_signals,
    fit_correction,
    generic_correction,
    lowpass,
    plot_correction,
    structure_verdict,
    unexplained_report,
)

__all__ = [
    "choose_base",
    "make_split",
    "fit_extended",
    "effect_evidence",
    "diagnose",
    "Diagnosis",
    "ResidualArrays",
    "Segment",
    "Split",
    "autocorrelation",
    "ljung_box",
    "cross_correlation",
    "effective_n",
    "candidate_signals",
    "signal_correlations",
    "whiteness_report",
    "LABEL",
    "lowpass",
    "expand_signals",
    "fit_correction",
    "apply_correction",
    "cv_ridge",
    "generic_correction",
    "structure_verdict",
    "describe",
    "unexplained_report",
    "plot_correction",
]
