"""Trained-range checks: where, when and how far a new input leaves the range a model was fitted on.

A fitted hysteresis model extrapolates outside its training range (operators the data never moved,
a polynomial outside its support), and an excursion can leave a lasting memory (measured on an
independent plant: the plant's own output shifted by 32x the noise for the rest of the record after
one excursion 0.65 V above the trained maximum).  `fit` therefore stores the training range of the
raw input and, for models with an internal hysteresis input (a cascade's thermal state), of that
effective input; `simulate`, `control` and `sweep` compare new inputs against both and warn with
the time, the duration and the size of each exit.
"""

from __future__ import annotations

import numpy as np

#: Exits smaller than this fraction of the fitted span are counted in a range check but not warned about.  Why: a new
#: record's first thermal state a hair below the training minimum (a cold start on a record whose training started a
#: few mV warmer) or an input printed with more digits than the training file's (1.9e-05 V below the min on a 5.6 V
#: span) warned on 3 of 4 in-range simulations of a new-user trial, always at up to 0.04 % of the span; the exits that
#: mattered there were 14.5-49 % of the span (+0.51 V on a 3.52 V range, a thermal state +49 %).  1 % is half the
#: branch check's deadband (`data.split.COVERAGE_TOL`, 2 %): well inside what the model's own branches resolve.
RANGE_TOL = 0.01

EFFECTIVE_RULE = (
    "min and max of the model's hysteresis input (the thermal state a cascade's hysteresis sees) over the training samples "
    "and the fitted start state before a trained first sample, computed with the saved model"
)


def effective_values(model, u, dt) -> np.ndarray | None:
    """The model's hysteresis input along ``u`` (None for a model that sees its input directly)."""
    if not hasattr(model, "hysteresis_input") or not hasattr(model, "thermal"):
        return None
    import jax.numpy as jnp

    return np.asarray(model.hysteresis_input(jnp.asarray(u, dtype=jnp.float64), jnp.asarray(dt, dtype=jnp.float64)))


def effective_range(segments) -> list[float] | None:
    """Trained range of the hysteresis input of a model with a thermal stage over ``[(model, u, dt, mask or None)]``
    (a record each, each run by its own model: a joint fit's per-record starts): the training samples, and the start
    state the model put before a segment whose first sample it was fitted on.  Why the start: a cold or at-rest start is
    a state the fit saw (its operators begin there), but the first sample is already one step warmer; leaving it out warned
    "outside the trained range" (1.3 % of the span) on in-range cold-start records and on every closed-loop run from rest
    in a new-user trial.  None for a model without a thermal stage or with a non-finite state."""
    vals = []
    for model, u, dt, mask in segments:
        x = effective_values(model, u, dt)
        if x is None or not np.all(np.isfinite(x)):
            return None
        m = np.ones(x.shape[0], bool) if mask is None else np.asarray(mask, bool)
        vals.append(x[m])
        start = getattr(model, "hysteresis_start", None)
        if m.size and m[0] and start is not None:
            x0 = start(np.asarray(u, dtype=np.float64), dt)
            if x0 is not None and np.isfinite(float(x0)):
                vals.append(np.array([float(x0)]))
    vals = [v for v in vals if v.size]
    return value_range(np.concatenate(vals)) if vals else None


def hysteresis_values(model, u, dt) -> np.ndarray | None:
    """What the model's hysteresis walks along ``u``: the effective input (`effective_values`) of a model with a
    thermal stage, the input itself for a model whose hysteresis sees it directly (a temperature or pressure record),
    None for a model without a hysteresis."""
    x = effective_values(model, u, dt)
    if x is not None:
        return x
    from ._hysteresis import hysteresis_of

    return np.asarray(u, dtype=np.float64) if hysteresis_of(model) is not None else None


def value_range(values, mask=None) -> list[float]:
    """[min, max] of ``values`` (over ``mask`` when given) as JSON-able floats."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.asarray(mask, dtype=bool)] if mask is not None else v
    return [float(np.min(v)), float(np.max(v))]


def _stretches(out: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index pairs of the runs of True in ``out``."""
    d = np.diff(np.concatenate([[0], out.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def range_tolerance(lo: float, hi: float) -> float:
    """How far a value may leave [lo, hi] before a range check warns: `RANGE_TOL` of the span (0 for a zero span)."""
    return RANGE_TOL * max(float(hi) - float(lo), 0.0)


def _when(a: int, b: int, dt: float | None, t0: float) -> str:
    """``1026.6 s for 0.1 s`` (sample ``a`` at ``t0 + a dt``) with a sample time, else ``sample a for b - a samples``."""
    return f"{t0 + a * dt:.6g} s for {(b - a) * dt:.3g} s" if dt else f"sample {a} for {b - a} samples"


def range_check(
    values, fitted_range, column: str = "input", *, dt: float | None = None, what: str = "input", t0: float = 0.0
) -> dict:
    """How far, how often and when ``values`` leave ``fitted_range`` = [lo, hi].

    Returns a JSON-able dict: the range, samples below and above (every one, however small the exit), the largest exits
    (in the values' units and in % of the fitted span), the ``tolerance`` (`RANGE_TOL` of the span), the exit stretches
    beyond it (first sample, and seconds when ``dt`` is given) and a ``warning`` sentence when any sample is outside by
    more than the tolerance; ``note`` when the range is unknown.  ``t0``: the time of the first sample (a record's own
    time axis, so the times match its time column); 0 for a plain array.
    """
    v = np.asarray(values, dtype=np.float64)
    if not (isinstance(fitted_range, (list, tuple)) and len(fitted_range) == 2):
        return {
            "fitted_range": None,
            "checked": False,
            "note": f"the model file carries no training {what} range (not a fit.json of this version): range not checked",
        }
    lo, hi = float(fitted_range[0]), float(fitted_range[1])
    span = hi - lo
    tol = range_tolerance(lo, hi)
    n_strict = int(np.sum(v < lo) + np.sum(v > hi))
    below, above = v < lo - tol, v > hi + tol  # the exits that are warned about
    n_out = int(below.sum() + above.sum())
    out = {
        "what": what,
        "fitted_range": [lo, hi],
        "checked": True,
        "input_range": [float(v.min()), float(v.max())],
        "n_samples": int(v.size),
        "n_below": int(np.sum(v < lo)),
        "n_above": int(np.sum(v > hi)),
        "fraction_outside": n_strict / v.size,
        "max_below": float(max(lo - v.min(), 0.0)),
        "max_above": float(max(v.max() - hi, 0.0)),
        "tolerance": {"fraction_of_span": RANGE_TOL, "value": tol},
        "n_beyond_tolerance": n_out,
        "n_within_tolerance": n_strict - n_out,
    }
    if not n_out:
        out["n_exits"] = 0
        return out
    runs = _stretches(below | above)
    out["n_exits"] = len(runs)
    out["exits"] = [
        {"start_sample": a, "end_sample": b, **({"start_s": t0 + a * dt, "duration_s": (b - a) * dt} if dt else {})}
        for a, b in runs[:20]
    ]

    def where(a, b):
        return _when(a, b, dt, t0)

    parts = []
    for mask, side, size in ((above, "above the max", out["max_above"]), (below, "below the min", out["max_below"])):
        if mask.any():
            first = _stretches(mask)[0]
            parts.append(
                f"{int(mask.sum())} {side} by up to {size:.4g}"
                + (f" ({100 * size / span:.1f} % of the fitted span)" if span > 0 else "")
                + f", first at {where(*first)}"
            )
    longest = max(runs, key=lambda r: r[1] - r[0])
    out["warning"] = (
        f"{what} '{column}' leaves the range the model was fitted on [{lo:.6g}, {hi:.6g}]: {n_out} of {v.size} samples "
        f"({100 * n_out / v.size:.1f} %) outside by more than {100 * RANGE_TOL:g} % of the span in {len(runs)} stretch(es), "
        f"the longest at {where(*longest)} ({'; '.join(parts)})" + _EXTRAPOLATES
    )
    return out


#: `output_check` warns when the model's output leaves the output range it was fitted on by more than this fraction of
#: that range's span while its (hysteresis) input stays inside the trained range.  Why: a plant's own output does not do
#: that; measured on two independent simulators over held-out parts whose thermal state stayed inside the training part's
#: range, the true output left the training output range by at most 6.0 % of its span (plant A, 40 random cells, seeds
#: 200-239) and 2.2 % (plant B, 32 records of seeds 12-13, 30-32, 38-39).  With the thermal state outside its range the
#: true output left by up to 9 spans (plant B, 30-50x the thermal exit in its own spans), so there the check only notes.
OUTPUT_TOL = 0.25


def output_check(y, fitted_range, *, input_inside: bool, dt: float | None = None, t0: float = 0.0) -> dict:
    """How far the model's output ``y`` leaves ``fitted_range`` (fit.json ``data.output_range``): a ``warning`` when it
    does by more than `OUTPUT_TOL` of the span while the input stays inside its trained range (``input_inside``), a
    ``note`` when the input leaves its range too (the output may then rightly leave its own)."""
    if not (isinstance(fitted_range, (list, tuple)) and len(fitted_range) == 2):
        return {"what": "model output", "checked": False, "note": "the model file carries no fitted output range"}
    v = np.asarray(y, dtype=np.float64)
    lo, hi = float(fitted_range[0]), float(fitted_range[1])
    span = hi - lo
    tol = OUTPUT_TOL * span
    out_of = (v < lo - tol) | (v > hi + tol)
    size = float(max(v.max() - hi, lo - v.min(), 0.0))
    out = {
        "what": "model output",
        "checked": True,
        "fitted_range": [lo, hi],
        "model_output_range": [float(v.min()), float(v.max())],
        "max_outside": size,
        "max_outside_spans": size / span if span > 0 else None,
        "tolerance": {"fraction_of_span": OUTPUT_TOL, "value": tol},
        "n_beyond_tolerance": int(out_of.sum()),
        "input_inside": bool(input_inside),
    }
    if not out_of.any() or span <= 0:
        return out
    a, b = _stretches(out_of)[0]
    text = (
        f"the model's output leaves the range of the output it was fitted on [{lo:.6g}, {hi:.6g}] by up to {size:.4g} "
        f"({size / span:.2g}x that span; {int(out_of.sum())} of {v.size} samples beyond {100 * OUTPUT_TOL:g} % of it, first "
        f"at {_when(a, b, dt, t0)})"
    )
    if input_inside:
        out["warning"] = (
            text + " while its input stays inside the trained range: an actuator's own output does not do that (on two "
            "independent plants it stayed within 6 % of the span), so the model extrapolates on a branch its training "
            "never walked there; do not trust those samples (fit a record that walks them)"
        )
    else:
        out["note"] = text + "; the input leaves its trained range too, so the output may rightly leave its own"
    return out


#: Cells of the trained span of the hysteresis input in `trained_branches` (a sample is on a trained branch when its
#: cell or a neighbour was visited in training in the same direction: about the 2 % tolerance of `branch_coverage`).
BRANCH_CELLS = 50
#: `branch_check` warns when the new input walks untrained branches over at least this fraction of the trained span
#: (however briefly: measured on an independent plant, the last 4 % of a record cooling through 30 % of the span on an
#: untrained branch was predicted 8 mm off on a 2.4 mm stroke).
BRANCH_WARN = 0.1


def _branch_cells(x, lo, span):
    return np.clip(np.floor((np.asarray(x, float) - lo) / span * BRANCH_CELLS), 0, BRANCH_CELLS - 1).astype(int)


def trained_branches(x, mask=None) -> dict:
    """Cells of the hysteresis input ``x`` that the training samples (``mask``) visit on a rising and on a falling branch.

    Stored in fit.json (``data.trained_branches``) so that `smafl simulate` can say when a new drive walks the model's
    hysteresis input along a branch training never saw (`branch_check`), which a range check cannot: on an independent
    plant a wire heated in steps and never cooled in training was predicted 8 mm (3.3x the record's range) off once the
    new drive let it cool through temperatures the training had visited only while heating.  Several records (a joint
    fit, the segments of a split): `trained_branches_of`.
    """
    return trained_branches_of([(x, mask)])


def trained_branches_of(segments) -> dict:
    """`trained_branches` over several trajectories ``[(x, mask or None), ...]``: one range over all their training
    samples, each trajectory's branch directions on its own (joining two records would invent a move between them),
    the cells visited in either."""
    from ..data.split import COVERAGE_TOL, branch_directions

    segs = [(np.asarray(x, float), np.ones(np.shape(x)[0], bool) if m is None else np.asarray(m, bool)) for x, m in segments]
    if not segs or not any(m.any() for _, m in segs):
        raise ValueError("trained_branches: no training samples")
    lo, hi = value_range(np.concatenate([x[m] for x, m in segs]))
    span = (hi - lo) or 1.0
    rising, falling = set(), set()
    for x, m in segs:
        d = branch_directions(x, COVERAGE_TOL * span)
        c = _branch_cells(x, lo, span)
        # samples before the first move (d == 0) belong to either branch
        rising.update(c[m & (d >= 0)].tolist())
        falling.update(c[m & (d <= 0)].tolist())
    return {
        "range": [lo, hi],
        "cells": BRANCH_CELLS,
        "deadband": COVERAGE_TOL * span,
        "rising": sorted(rising),
        "falling": sorted(falling),
        "rule": (
            f"cells of {BRANCH_CELLS} over the trained range of the model's hysteresis input visited by the training samples, "
            "per branch direction (the last move larger than the deadband)"
            + (f"; {len(segs)} records, each with its own directions" if len(segs) > 1 else "")
        ),
    }


def branch_check(x, trained: dict | None, *, dt: float | None = None, t0: float = 0.0) -> dict:
    """Samples of ``x`` inside the trained range that lie on a branch training never visited (`trained_branches`), and
    the share of the trained span they cross; a ``warning`` (with the first such stretch, at ``t0 + k dt``) when that
    share reaches `BRANCH_WARN`."""
    if not trained:
        return {"checked": False, "what": "branches", "note": "the model file carries no trained branches: branches not checked"}
    from ..data.split import branch_directions

    x = np.asarray(x, float)
    lo, hi = (float(v) for v in trained["range"])
    span = (hi - lo) or 1.0
    d = branch_directions(x, float(trained["deadband"]))
    c = _branch_cells(x, lo, span)
    inside = (x >= lo) & (x <= hi)
    ok = np.ones(x.size, bool)
    for k, name in ((1, "rising"), (-1, "falling")):
        seen = np.zeros(BRANCH_CELLS + 2, bool)
        seen[np.asarray(trained[name], int) + 1] = True
        near = seen[c] | seen[c + 1] | seen[c + 2]  # the cell or a neighbour (seen is shifted by one)
        ok[d == k] = near[d == k]
    off = inside & ~ok
    n_in = int(inside.sum())
    # how much of the trained span the untrained stretches cross (distinct cells per direction), not how long they last
    extent = sum(len(set(c[off & (d == k)].tolist())) for k in (1, -1)) / BRANCH_CELLS
    out = {
        "what": "branches",
        "checked": True,
        "n_inside": n_in,
        "n_untrained": int(off.sum()),
        "fraction_untrained": float(off.sum() / n_in) if n_in else 0.0,
        "untrained_span_fraction": float(extent),
        "by_direction": {name: int(np.sum(off & (d == k))) for k, name in ((1, "rising"), (-1, "falling"))},
    }
    if off.any() and extent >= BRANCH_WARN:
        a, b = _stretches(off)[0]
        where = _when(a, b, dt, t0)
        worst = max(out["by_direction"], key=out["by_direction"].get)
        out["warning"] = (
            f"the model's hysteresis input walks branches its training never visited, across {100 * extent:.0f} % of the "
            f"trained span ({out['n_untrained']} of the {n_in} samples inside the trained range, mostly {worst}; first at "
            f"{where}); the model extrapolates there even though the input stays in range (fit a record that visits both "
            "branches)"
        )
    return out


def model_range_checks(model, data_info: dict, u, dt, column: str = "input", *, t0: float = 0.0) -> list[dict]:
    """Raw-input and effective-input (hysteresis input) checks of ``u`` against a fit.json's ``data`` ranges, and the
    branch check of the effective input against ``data.trained_branches`` (when the file has them).  ``t0``: the time
    of the first sample on the record's own axis (times in the warnings and the JSON), 0 without a record."""
    checks = [range_check(u, data_info.get("input_range"), column, dt=dt, what="input", t0=t0)]
    eff = data_info.get("effective_input_range")
    if eff is not None:
        x = effective_values(model, u, dt)
        if x is not None:
            checks.append(range_check(x, eff, "hysteresis input", dt=dt, what="effective input", t0=t0))
            if checks[0].get("warning") and not checks[-1].get("warning"):
                # The thermal lag smooths the drive: the hysteresis extrapolates only when its own input leaves its
                # range.  Measured (new-user trial 7, an independent plant fitted on a multisine drive): the 0 V off
                # phases of a PWM run were 69 % "outside the fitted range" of the raw drive, with the thermal state
                # inside its trained range, and the run scored 1.04x the noise against the plant's clean output.
                raw = checks[0]
                raw["note"] = (
                    raw.pop("warning").split("; the model extrapolates there")[0]
                    + "; the thermal state the hysteresis sees stays inside its trained range (the lag smooths the drive), "
                    "so the model does not extrapolate there"
                )
            if data_info.get("trained_branches"):
                checks.append(branch_check(x, data_info["trained_branches"], dt=dt, t0=t0))
    elif data_info.get("trained_branches") and effective_values(model, u, dt) is None:
        # a hysteresis that sees the input directly: its branches are the input's own
        x = hysteresis_values(model, u, dt)
        if x is not None:
            checks.append(branch_check(x, data_info["trained_branches"], dt=dt, t0=t0))
    return _said_held(model, checks)


#: The end of a range warning for a model that extrapolates, and the one for a model that holds its input there.
_EXTRAPOLATES = "; the model extrapolates there, and a hysteresis model keeps a memory of the excursion afterwards"
_HOLDS = (
    "; the model holds its hysteresis input at the edge of that range there (fit.json settings.hold_input) instead of "
    "extrapolating, so it predicts no response beyond it"
)


_HOLDS_BELOW = (
    "; below that range the model holds its hysteresis input at the edge (fit.json settings.hold_input) instead of "
    "extrapolating; above it the model extrapolates, and a hysteresis model keeps a memory of the excursion afterwards"
)


def _said_held(model, checks):
    """Range warnings of a model whose hysteresis holds its input (`AbstractHysteresis.with_held`) say so; a hold of
    the low side only (a cascade's thermal state) is said on the hysteresis input's own check."""
    from ._hysteresis import hysteresis_of

    held = getattr(hysteresis_of(model), "held", None)
    if held is None:
        return checks
    both = held[0] is not None and held[1] is not None
    for chk in checks:
        if chk.get("warning") and chk.get("what") in (("input", "effective input") if both else ("effective input",)):
            chk["warning"] = chk["warning"].replace(_EXTRAPOLATES, _HOLDS if both else _HOLDS_BELOW)
    return checks
