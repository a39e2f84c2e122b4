"""Initial-state rules for running a fitted model on a new record.

A fit stores the start state of *its* record (thermal ``u0``, the operators' fitted memory).  A new
record starts wherever its own history left the actuator, so `simulate` takes a rule:

- ``"fit"``: the fitted model's own start, unchanged (right when the new record starts as the fitted one);
- ``"steady"``: at rest with the first input sample, operators descended to it (the paper's convention);
- ``"cold"``: at ambient temperature (thermal state 0), operators descended;
- ``"estimate"``: the start (thermal state x operator memory, a small grid) whose output best matches the
  measured output over the first part of the record (`estimate_initial_state`); needs a measured column.
"""

from __future__ import annotations

import dataclasses
from typing import Any, TypeVar

import numpy as np
from numpy.typing import ArrayLike

from .._errors import UserInputError

__all__ = ["INITIAL_STATE_RULES", "with_initial_state", "estimate_initial_state"]

INITIAL_STATE_RULES = ("fit", "steady", "cold", "estimate")
#: Thermal start candidates of "estimate" besides steady and cold: initial effective voltage / input maximum.
_THERMAL_FRACTIONS = (0.35, 0.65, 0.95)
#: Operator memory candidates of "estimate" (logits of `EUPI.with_fitted_memory`); None = the model's own.
_MEMORY_LOGITS = {"as fitted": None, "descended": 8.0, "midway": 0.0, "ascended": -8.0}


_Model = TypeVar("_Model")


def _thermal_variant(model, rule, u_hi=None):
    th = getattr(model, "thermal", None)
    if th is None:
        return model
    if rule == "steady":
        new = dataclasses.replace(th, init="steady", u0=None)
    elif rule == "cold":
        new = dataclasses.replace(th, init="ambient", u0=None)
    else:  # a fraction of the input maximum
        new = dataclasses.replace(th, init="given", u0=np.asarray(float(rule) * u_hi))
    return dataclasses.replace(model, thermal=new)


def _memory_variant(model, logit):
    h = getattr(model, "hysteresis", None)
    if h is None or logit is None or not hasattr(h, "with_fitted_memory"):
        return model
    return model.with_hysteresis(h.with_fitted_memory(logit))


def _descended(model):
    h = getattr(model, "hysteresis", None)
    if h is None or getattr(h, "init", None) != "fitted":
        return model
    return model.with_hysteresis(dataclasses.replace(h, init="descended", memory=None))


def _start_words(model, t_rule, u_first: float, u_hi: float | None) -> dict[str, Any]:
    """The thermal start of ``model`` (set by ``t_rule``) as the effective voltage it stands for, and in words."""
    th = getattr(model, "thermal", None)
    if th is None:
        return {}
    try:
        v = float(th.start_voltage(u_first))
    except TypeError:  # one start per record of a joint fit: no single voltage
        return {"thermal_description": th.start_description()}
    if t_rule == "fit":  # the model's own rule
        t_rule = {"steady": "steady", "ambient": "cold"}.get(th.init, "fit")
    if t_rule == "fit":
        words = f"as if held at {v:.3g} V (as fitted)"
    elif t_rule == "steady":
        words = f"at rest with the first input ({v:.3g} V)"
    elif t_rule == "cold":
        words = "cold (ambient, 0 V)"
    else:
        words = f"as if held at {v:.3g} V ({100 * float(t_rule):.0f} % of the record's maximum input, {u_hi:.3g} V)"
    return {"u0_V": v, "thermal_description": f"thermal state at t=0 {words}"}


def _memory_words(model, label: str | None = None) -> str:
    """The operator memory in words: the estimate's ``label`` (with the model's rule when "as fitted"), else the rule."""
    init = getattr(getattr(model, "hysteresis", None), "init", None)
    if label is None:
        return f"operator memory {'as fitted' if init in (None, 'fitted') else init}"
    return f"operator memory {label}" + (f" ({init})" if label == "as fitted" and init else "")


def estimate_initial_state(
    model: _Model, u: ArrayLike, y: ArrayLike, dt: float, *, window: int | None = None
) -> tuple[_Model, dict[str, Any]]:
    """``(model, info)``: the start candidate that best matches ``y`` over the first ``window`` samples.

    ``window`` defaults to the first 20 % of the record, at least 5 thermal time constants where the model
    has a thermal part (the start matters until the lag and the operators have forgotten it).
    """
    from ._simulate import simulate

    u = np.asarray(u, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if y.shape != u.shape or not np.all(np.isfinite(y)):
        raise UserInputError("estimating the initial state needs a finite measured output of the input's length")
    th = getattr(model, "thermal", None)
    n = u.shape[0]
    if window is None:
        window = max(int(0.2 * n), int(5.0 / float(th.k1) / dt) if th is not None else 0)
    window = int(min(max(window, 10), n))
    u_hi = float(np.max(u)) if np.max(u) > 0 else 1.0
    thermal = ("fit", "steady", "cold", *_THERMAL_FRACTIONS) if th is not None else ("fit",)
    rows, best = [], None
    for t_rule in thermal:
        base = model if t_rule == "fit" else _thermal_variant(model, t_rule, u_hi)
        for m_label, logit in _MEMORY_LOGITS.items():
            cand = _memory_variant(base, logit)
            yhat = np.asarray(simulate(cand, u, dt))[:window]
            sse = float(np.sum((yhat - y[:window]) ** 2))
            sse = sse if np.isfinite(sse) else np.inf
            rows.append({"thermal": t_rule, "memory": m_label, "rmse_first": float(np.sqrt(sse / window))})
            if best is None or sse < best[0]:
                best = (sse, cand, t_rule, m_label)
    info = {
        "rule": "estimate",
        "window_samples": window,
        "thermal": best[2],
        "memory": best[3],
        **_start_words(best[1], best[2], float(u[0]), u_hi),
        "memory_description": _memory_words(best[1], best[3]),
        "candidates": rows,
    }
    return best[1], info


def with_initial_state(
    model: _Model, rule: str, u: ArrayLike | None = None, y: ArrayLike | None = None, dt: float | None = None
) -> tuple[_Model, dict[str, Any]]:
    """``(model, info)`` with the start state set by ``rule`` (see the module docstring)."""
    if rule not in INITIAL_STATE_RULES:
        raise UserInputError(f"initial state rule must be one of {INITIAL_STATE_RULES}, got {rule!r}")
    if rule == "fit":
        return model, {"rule": "fit"}
    if rule == "estimate":
        if y is None:
            raise UserInputError(
                "the initial-state rule 'estimate' needs the measured output (y; from the command line: --measured COLUMN)"
            )
        return estimate_initial_state(model, u, y, dt)
    started = _descended(_thermal_variant(model, rule))
    words = _start_words(started, rule, float(np.asarray(u)[0]), None) if u is not None else {}
    return started, {"rule": rule, **words, "memory_description": _memory_words(started)}
