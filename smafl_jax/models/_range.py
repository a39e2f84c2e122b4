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

EFFECTIVE_RULE = (
    "min and max of the model's hysteresis input (the thermal state a cascade's hysteresis sees) over the training samples, "
    "computed with the saved model"
)


def effective_values(model, u, dt) -> np.ndarray | None:
    """The model's hysteresis input along ``u`` (None for a model that sees its input directly)."""
    if not hasattr(model, "hysteresis_input") or not hasattr(model, "thermal"):
        return None
    import jax.numpy as jnp

    return np.asarray(model.hysteresis_input(jnp.asarray(u, dtype=jnp.float64), jnp.asarray(dt, dtype=jnp.float64)))


def value_range(values, mask=None) -> list[float]:
    """[min, max] of ``values`` (over ``mask`` when given) as JSON-able floats."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.asarray(mask, dtype=bool)] if mask is not None else v
    return [float(np.min(v)), float(np.max(v))]


def _stretches(out: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index pairs of the runs of True in ``out``."""
    d = np.diff(np.concatenate([[0], out.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def range_check(values, fitted_range, column: str = "input", *, dt: float | None = None, what: str = "input") -> dict:
    """How far, how often and when ``values`` leave ``fitted_range`` = [lo, hi].

    Returns a JSON-able dict: the range, samples below and above, the largest exits (in the values'
    units and in % of the fitted span), the exit stretches (first sample, and seconds when ``dt`` is
    given) and a ``warning`` sentence when any sample is outside; ``note`` when the range is unknown.
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
    below, above = v < lo, v > hi
    n_out = int(below.sum() + above.sum())
    out = {
        "what": what,
        "fitted_range": [lo, hi],
        "checked": True,
        "input_range": [float(v.min()), float(v.max())],
        "n_samples": int(v.size),
        "n_below": int(below.sum()),
        "n_above": int(above.sum()),
        "fraction_outside": n_out / v.size,
        "max_below": float(lo - v.min()) if below.any() else 0.0,
        "max_above": float(v.max() - hi) if above.any() else 0.0,
    }
    if not n_out:
        return out
    runs = _stretches(below | above)
    out["n_exits"] = len(runs)
    out["exits"] = [
        {"start_sample": a, "end_sample": b, **({"start_s": a * dt, "duration_s": (b - a) * dt} if dt else {})}
        for a, b in runs[:20]
    ]

    def where(a, b):
        return f"{a * dt:.4g} s for {(b - a) * dt:.3g} s" if dt else f"sample {a} for {b - a} samples"

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
        f"({100 * n_out / v.size:.1f} %) outside in {len(runs)} stretch(es), the longest at {where(*longest)} "
        f"({'; '.join(parts)}); the model extrapolates there, and a hysteresis model keeps a memory of the excursion afterwards"
    )
    return out


def model_range_checks(model, data_info: dict, u, dt, column: str = "input") -> list[dict]:
    """Raw-input and effective-input (hysteresis input) checks of ``u`` against a fit.json's ``data`` ranges."""
    checks = [range_check(u, data_info.get("input_range"), column, dt=dt, what="input")]
    eff = data_info.get("effective_input_range")
    if eff is not None:
        x = effective_values(model, u, dt)
        if x is not None:
            checks.append(range_check(x, eff, "hysteresis input", dt=dt, what="effective input"))
    return checks
