"""`smafl paper`: the paper's whole story on the bundled records, in one run and one report."""

from ._paper import PAPER_VALUES, run_paper

__all__ = [
    "run_paper",
    "PAPER_VALUES",
]
