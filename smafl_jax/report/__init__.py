"""Writing results: fit and diagnosis outputs (fit.json, report.md / report.html, figures), the small
report builder, the uncertainty figures and the provenance header of every fit.json-format file.
"""

from .._choices import HYSTERESIS
from ._plots_bayes import corner_figure, parameter_label, predictive_loop_figure, predictive_time_figure, trace_figure
from ._provenance import PACKAGES, fit_header, record_data, versions
from ._report import write_diagnosis
from ._report_fit import K2_NOTE, MODELS, build_model, choose_structure, fit_record, write_fit_outputs
from ._reportdoc import Report, axis_label, fmt, unit_of

__all__ = [
    "versions",
    "fit_header",
    "record_data",
    "PACKAGES",
    "write_diagnosis",
    "MODELS",
    "build_model",
    "choose_structure",
    "fit_record",
    "write_fit_outputs",
    "Report",
    "fmt",
    "axis_label",
    "unit_of",
    "corner_figure",
    "trace_figure",
    "predictive_time_figure",
    "predictive_loop_figure",
    "parameter_label",
    # Documented helpers that tests and experiments use (issue 12: they import the sub-package API).
    "K2_NOTE",
    "HYSTERESIS",
]
