"""Train/validation splits for one record (masks over its samples).

Hysteresis and thermal models carry memory, so a split never cuts the record
into separate simulations: the model always runs through the whole record and
the split only decides which samples enter the loss (train) and which are
scored afterwards (validation).

Rules (fixed, documented, never tuned to a result):

- ``"branch"``: for records with a ``branch`` column (reversal-curve / FORC
  data).  Branch labels are sorted; the 3rd, 6th, 9th, ... (positions
  ``i % 3 == 2``, i from 0) are held out.  The first branch (the largest
  excursion in FORC data) always trains, so validation is interpolation
  between trained branches, not extrapolation.
- ``"time"``: the last ``val_fraction`` (default 30 %) of the samples.
- ``"interleaved"``: every third of ten equal blocks held out (not the first), at the offset whose held-out part
  the training part covers best (`smafl_jax.data.split.interleaved`): for a record whose last part leaves the
  levels or directions the first part visited (a slow ramp, a triangle), where the time block measures
  extrapolation.  Chosen explicitly; ``"auto"`` keeps the time block.
- ``"none"``: everything trains; there are no validation metrics.
- ``"auto"``: ``"branch"`` when the record has a ``branch`` column, else ``"time"``.

The rules themselves (where the time block starts, which branches are held out) live in
`smafl_jax.data.split` (`time_cut`, `branch_partition`), shared with diagnose and cross-validation;
this module turns them into masks over one whole-record simulation.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._errors import UserInputError
from ..data.split import BRANCH_EVERY, branch_partition, time_cut

__all__ = ["split_masks", "interpolated_note", "SPLITS", "INTERPOLATED_RULE"]

from .._choices import SPLITS

BRANCH_POSITION = 2  # the residue of `branch_partition` used by fit: the 3rd, 6th, ... sorted labels


def split_masks(
    record: Any, split: str = "auto", *, val_fraction: float = 0.3, branch_column: str = "branch"
) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """``(train_mask, val_mask, info)`` for ``record`` (boolean arrays over its samples).

    Samples that resampling interpolated across a gap (`Record.measured` False) are in neither mask: they are not
    measurements, so they neither train the model nor score it (``info["interpolated_left_out"]`` counts them)."""
    train, val, info = _split_masks(record, split, val_fraction=val_fraction, branch_column=branch_column)
    ok = np.asarray(getattr(record, "measured", np.ones(len(record), bool)), bool)
    if not ok.all():
        train, val = train & ok, val & ok
        info = {**info, "interpolated_left_out": int(np.sum(~ok)), "interpolated_rule": INTERPOLATED_RULE}
        parts = (("training", train), ("validation", val)) if info["kind"] != "none" else (("training", train),)
        for name, m in parts:
            if int(m.sum()) < 3:
                raise UserInputError(
                    f"{record.path or record.name}: the {name} part keeps {int(m.sum())} measured samples once the "
                    f"{int(np.sum(~ok))} samples interpolated across resampling gaps are left out; need >= 3"
                )
    return train, val, info


#: How a resampled record's interpolated samples are treated (fit.json ``split.interpolated_rule``).
INTERPOLATED_RULE = (
    "samples that --resample interpolated across a gap of the logger (strictly inside a bridged interval) carry no "
    "weight in the fit and are left out of every score; the model still runs through them"
)


def interpolated_note(records) -> str:
    """The fit note of records resampled across gaps: how many samples were interpolated and what was done with them."""
    n = sum(int(np.sum(~r.measured)) for r in records)
    total = sum(len(r) for r in records)
    return f"{n} of {total} samples ({n / total:.1%}) were interpolated across resampling gaps: " + INTERPOLATED_RULE


def _split_masks(record, split, *, val_fraction, branch_column):
    n = len(record)
    if split not in SPLITS:
        raise UserInputError(f"unknown split {split!r}; choose one of {SPLITS}")
    if split == "auto":
        split = "branch" if branch_column in record.extra else "time"
    if split == "none":
        return np.ones(n, bool), np.zeros(n, bool), {"kind": "none", "rule": "all samples train; no validation"}
    if split == "time":
        if not (isinstance(val_fraction, (int, float)) and 0.0 < val_fraction < 1.0):
            raise UserInputError(f"--val-fraction must be in (0, 1), got {val_fraction}")
        n_val = n - time_cut(n, val_fraction)
        if n_val < 3 or n - n_val < 3:
            raise UserInputError(f"time split leaves {n - n_val} train and {n_val} validation samples; need >= 3 each")
        val = np.zeros(n, bool)
        val[n - n_val :] = True
        info = {
            "kind": "time",
            "rule": f"last {val_fraction:.0%} of the samples held out",
            "val_fraction": float(val_fraction),
            "validation_start_time_s": float(record.time[n - n_val]),
        }
        return ~val, val, info
    if split == "interleaved":
        from ..data.split import interleaved

        sp = interleaved(record, val_fraction)
        val = np.asarray(sp.test[0].mask, bool).copy()
        info = {
            "kind": "interleaved",
            "rule": sp.rule,
            "val_fraction": float(val_fraction),
            "validation_blocks": sp.test_labels[0],
        }
        return ~val, val, info
    if branch_column not in record.extra:
        raise UserInputError(
            f"split 'branch' needs a numeric '{branch_column}' column; the record has {sorted(record.extra) or 'no extra columns'}"
        )
    labels = np.asarray(record.extra[branch_column])
    branches = np.unique(labels)
    held = np.asarray(branch_partition(branches, BRANCH_POSITION)[1], dtype=branches.dtype)
    if held.size == 0:
        raise UserInputError(f"branch split needs at least {BRANCH_POSITION + 1} branches, the record has {branches.size}")
    val = np.isin(labels, held)
    info = {
        "kind": "branch",
        "rule": f"sorted branch labels at positions i % {BRANCH_EVERY} == {BRANCH_POSITION} held out (3rd, 6th, ...)",
        "branch_column": branch_column,
        "train_branches": [float(b) for b in branches if b not in held],
        "validation_branches": [float(b) for b in held],
    }
    return ~val, val, info
