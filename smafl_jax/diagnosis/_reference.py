"""`smafl fit`'s own default model as a reference for the diagnosis's gates (issue 13, session 68).

The diagnosis fits a base of its own (`choose_base`, `screened_base`, one variable-projection start and a symmetric
refinement), lighter than `smafl fit` (class screening on folds, the other hysteresis input, a gain prior, a full-rate
polish).  On a clean record of the independent plant A (tests/indep_plant.py seed 301, PWM 9 Hz, length sensor) the
diagnosis's base held out at 1.38x the noise and the gates accepted sensor_lead (+22 % on the held-out block and on
every fold), while `smafl fit REC` with its defaults held out at 1.00x on the very same block.  An effect that only
makes up for a lighter fit of the same model class is not a missing effect: where `smafl fit`'s default structure
holds out at the noise floor on the diagnosis's own held-out block, the gates' acceptance is withdrawn and the record
is treated as one whose base is at the floor.
"""

from __future__ import annotations

import time

import numpy as np

from .._errors import UserInputError
from ..data.split import HOLDOUT_FRACTION


def reference_heldout(record, split, noise_sd) -> dict | None:
    """Held-out RMSE of `smafl fit`'s default structure on the diagnosis's held-out block, with the noise multiple.

    The reference is `smafl fit REC --split time` (or ``--split interleaved``) with its defaults, stopped after the
    split fit (no whole-record refit): trained and scored on the diagnosis's own samples (`data.split.time_block` or
    `data.split.interleaved`, checked mask for mask).  None where the split is neither (a branch split is chosen
    differently by `smafl fit`); a dict with ``error`` and no noise multiple where that fit refuses the record.
    """
    if split.kind not in ("time", "interleaved") or len(split.test) != 1:
        return None
    from ..identify._split import split_masks
    from ..report._report_fit import _fit_structure

    mask = np.asarray(split.test[0].mask, dtype=bool)
    n = len(record)
    if mask.shape != (n,) or not mask.any():
        return None
    first = int(np.flatnonzero(mask)[0])
    # the time block's fraction from its first held-out sample; the interleaved rule's own (`data.split.interleaved`)
    fraction = (n - first) / n if split.kind == "time" else HOLDOUT_FRACTION
    try:
        same = np.array_equal(split_masks(record, split.kind, val_fraction=fraction)[1], mask)
    except UserInputError:
        same = False
    if not same:  # `smafl fit` would score other samples: no reference
        return None
    t0 = time.time()
    try:
        _, doc, _ = _fit_structure(record, model="auto", split=split.kind, val_fraction=fraction, refit=False)
    except UserInputError as e:  # a record the default fit refuses: no reference, said in diagnosis.json
        return {"rule": "smafl fit's default structure", "error": str(e), "over_noise": None}
    val = (doc.get("metrics") or {}).get("validation")
    if not val:
        return None
    rmse = float(val["rmse"])
    trained = f"first {100 * (1 - fraction):.3g} %" if split.kind == "time" else "same interleaved blocks"
    return {
        "rule": (
            f"smafl fit's default structure ({doc['model'].get('type', '?')}), split fit only: trained on the {trained} "
            "and scored on the diagnosis's held-out samples"
        ),
        "heldout_rmse": rmse,
        "over_noise": rmse / noise_sd if noise_sd else None,
        "seconds": time.time() - t0,
    }


def withdrawal(selected, reference_doc, base_over_noise, floor) -> tuple[dict, str | None]:
    """``({name: why}, warning)``: the gates' ``selected`` withdrawn when the reference fit (`reference_heldout`) holds
    out within ``floor`` times the noise SD, else ``({}, None)``."""
    ref = (reference_doc or {}).get("over_noise")
    if not selected or ref is None or ref > floor:
        return {}, None
    why = (
        f"smafl fit's default model holds out at {ref:.3g}x the noise SD on the same block (at the floor, <= {floor:g}x; "
        f"this diagnosis's base {base_over_noise:.3g}x): what it explains, a fuller fit without any effect explains too"
    )
    warning = (
        f"the calibrated gates accepted {', '.join(selected)}, but {why}; not selected, and the naming goes on as for a "
        "base at the noise floor (diagnosis.json base.reference_fit)"
    )
    return {n: why for n in selected}, warning
