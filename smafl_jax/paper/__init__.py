"""`smafl paper`: the paper's whole story on the bundled records, in one run and one report."""

from ._paper import (
    PAPER_VALUES,
    TIE_MARGIN,
    control_ranking,
    run_paper,
    section_bayes,
    section_cascade,
    section_control,
    section_diagnosis,
    section_eupi,
    section_joule,
)

__all__ = [
    "run_paper",
    "PAPER_VALUES",
    # Documented helpers that tests and experiments use (issue 12: they import the sub-package API).
    "TIE_MARGIN",
    "control_ranking",
    "section_bayes",
    "section_cascade",
    "section_control",
    "section_diagnosis",
    "section_eupi",
    "section_joule",
]
