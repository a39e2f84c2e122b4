"""`Diagnosis`: what `diagnose` returns (issue 12), in the manner of diffrax's / optimistix's ``Solution``.

A frozen dataclass rather than an ``eqx.Module``: it is made and read in plain Python (never passed through
``jit``), and its ``report`` is a nested dict of numbers and strings, not a PyTree of arrays.  It is not a
tuple either, so code written for the old ``(result, base, extended, split)`` return fails loudly instead of
silently unpacking the wrong fields.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import equinox as eqx
import numpy as np

from ._diagnose import Split

__all__ = ["Diagnosis", "ResidualArrays"]


@dataclasses.dataclass(frozen=True, eq=False)
class ResidualArrays:
    """Residuals (measured - simulated) on the scored samples of each part of the split, segments concatenated.

    ``base_*``: the base model's; ``extended_*``: the selected model's (the base's when nothing was selected).
    ``correction``: the generic residual regression of ``Diagnosis.unexplained`` (``train``, ``train_correction``,
    ``heldout``, ``heldout_correction``), None when it was not run or could not be fitted.
    """

    base_train: np.ndarray
    base_heldout: np.ndarray
    extended_train: np.ndarray
    extended_heldout: np.ndarray
    correction: dict[str, np.ndarray] | None = None


@dataclasses.dataclass(frozen=True, eq=False, repr=False)
class Diagnosis:
    """Result of `smafl_jax.diagnose` (the Python side of ``smafl diagnose``).

    The held-out figures are those of ``base`` and ``extended``, fitted on ``split.train`` only;
    ``deployed_base`` / ``deployed_extended`` are the same structures refitted on every sample of the record
    (``diagnose(refit=True)``, the default; None otherwise), the models to use on new data.
    ``report`` holds the content of ``diagnosis.json`` as computed (numpy scalars, NaN kept; no private keys);
    `to_json_dict` gives it as written (plain Python, NaN -> None).
    """

    selected: tuple[str, ...]  # accepted effects in the order they were added (or ("nonlocal_memory",))
    base: eqx.Module  # base model (EUPI or Cascade) fitted on the training part of the split
    extended: eqx.Module  # selected model (ExtendedModel or Preisach) fitted on the training part; the base if none
    split: Split  # the training / held-out split every held-out figure refers to
    report: dict[str, Any]  # diagnosis.json content
    residuals: ResidualArrays  # residual arrays behind report["residuals"] and the plots
    deployed_base: eqx.Module | None = None  # base refitted on the whole record (None without refit)
    deployed_extended: eqx.Module | None = None  # selected structure refitted on the whole record (None without refit)

    @property
    def model(self) -> eqx.Module:
        """The model to predict new data with: the deployed selected model, else its split fit (`extended_fit.json`)."""
        return self.extended if self.deployed_extended is None else self.deployed_extended

    @property
    def heldout_rmse_before(self) -> float:
        """Held-out RMSE of the base model (split fit)."""
        return float(self.report["base"]["heldout_rmse"])

    @property
    def heldout_rmse_after(self) -> float:
        """Held-out RMSE of the selected model (split fit; equal to the base's when nothing was selected)."""
        return float(self.report["extended"]["heldout_rmse"])

    @property
    def heldout_e_r_before(self) -> float:
        """Held-out relative error e_r (percent) of the base model."""
        return float(self.report["base"]["heldout"]["e_r_percent"])

    @property
    def heldout_e_r_after(self) -> float:
        """Held-out relative error e_r (percent) of the selected model."""
        return float(self.report["extended"]["heldout"]["e_r_percent"])

    @property
    def candidates(self) -> list[dict[str, Any]]:
        """One entry per applicable effect (evidence, fit, held-out gain, decision), in evidence order."""
        return self.report["candidates"]

    @property
    def unexplained(self) -> dict[str, Any] | None:
        """What the selected model leaves unexplained (``diagnose(unexplained=False)``: None)."""
        return self.report.get("unexplained")

    @property
    def ambiguous(self) -> list[str]:
        """Effects the data could not tell apart from the selected ones."""
        return self.report.get("ambiguous", [])

    @property
    def unspecific(self) -> list[str]:
        """Effects that each passed the calibrated test but explain the residual alike without sharing a lookalike
        group (nothing selected then: the residual is a misfit of the base model)."""
        return self.report.get("unspecific", [])

    @property
    def warnings(self) -> list[str]:
        """Warnings about the request (e.g. a requested effect that does not apply to this record)."""
        return self.report.get("warnings", [])

    def to_json_dict(self) -> dict[str, Any]:
        """The ``diagnosis.json`` dict: a fresh, strictly JSON-serialisable copy of ``report``."""
        from .._io import to_jsonable

        return to_jsonable(self.report)

    def __repr__(self) -> str:
        # the report and the arrays are long; the summary is what one wants at a prompt
        sel = ", ".join(self.selected) or "none"
        return (
            f"Diagnosis(selected=({sel}), base={type(self.base).__name__}, extended={type(self.extended).__name__}, "
            f"split={self.split.kind!r}, heldout_rmse {self.heldout_rmse_before:.4g} -> {self.heldout_rmse_after:.4g}, "
            f"deployed={self.deployed_extended is not None})"
        )
