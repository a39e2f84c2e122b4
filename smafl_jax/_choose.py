"""Automatic start for a fit: model structure, output orientation and thermal start state.

A record as users make it rarely starts at rest: the actuator may be cold with
the power on, warm with the power off, or anywhere between; the sensor may read
length (falling on contraction) instead of displacement; the drive may be a
voltage (thermal lag matters) or a temperature (no lag to model).  Each of
these is a discrete choice the gradient fit cannot make by itself, so it is
screened here with the cheap profiled initialiser (k1 profiled, gains by
bounded least squares) on the training samples, and the best candidate is the
start of the joint refinement.  Candidates compete on training loss only:
within one structure they have the same number of free parameters, so the
comparison is fair and needs no held-out data.

For a cascade the chosen start is turned into ``JouleThermal(init="given")``
with the initial effective voltage ``u0`` as a fitted parameter, so the
refinement can settle on any start temperature between cold and equilibrium.
"""

from __future__ import annotations

import dataclasses
import sys
import time

import jax.numpy as jnp
import numpy as np

from . import _config  # noqa: F401
from ._cascade import Cascade
from ._errors import UserInputError
from ._eupi import EUPI
from ._fit import as_fit_data, fit

__all__ = ["auto_structure", "screen_start", "COLD_FRACTION"]

#: Initial effective voltage of a "cold" start, as a fraction of the input maximum.  Not exactly 0: the
#: refinement fits ``u0`` through a softplus, whose gradient vanishes at 0 (a start there could never warm up).
COLD_FRACTION = 0.05

_VOLTAGE_UNITS = ("v", "volt", "volts")
_START_FRACTION = {"cold": COLD_FRACTION, "warm": 0.5, "hot": 0.9}


def auto_structure(record):
    """``("cascade" | "eupi", reason)``: the structure ``--model auto`` fits to this record.

    A drive voltage heats the actuator through a thermal lag (the paper's cascade); any other input
    (temperature, pressure, current already converted...) drives the hysteresis directly.
    """
    name = (record.input_name or "").lower()
    unit = str(dict(getattr(record, "units", {}) or {}).get(record.input_name, "")).strip().lower()
    voltage = "volt" in name or name.endswith("_v") or unit in _VOLTAGE_UNITS
    if voltage and float(np.min(record.u)) >= 0:
        return "cascade", f"input '{record.input_name}' is a drive voltage >= 0: Joule heating -> thermal lag -> EUPI"
    if voltage:
        return "eupi", f"input '{record.input_name}' is a voltage but goes below 0; Joule heating needs U >= 0, so static EUPI"
    return "eupi", f"input '{record.input_name}' is not a drive voltage: the hysteresis sees it directly (static EUPI)"


def _with_orientation(model, sign):
    if isinstance(model, EUPI):
        return dataclasses.replace(model, orientation=int(sign))
    return dataclasses.replace(model, hysteresis=dataclasses.replace(model.hysteresis, orientation=int(sign)))


def _with_sees(model, sees, u_hi):
    """Cascade copy whose hysteresis acts on ``sees`` (same operator grid, range rescaled)."""
    if model.sees == sees:
        return model
    e = model.hysteresis
    n_alpha, n_asym = np.shape(e.w)
    fresh = EUPI.from_range(
        0.0, u_hi if sees == "voltage" else u_hi * u_hi, n_sym=np.shape(e.v)[0], n_alpha=n_alpha, n_asym=n_asym,
        poly_order=np.shape(e.poly)[0] + 1, init=e.init, method=e.method, orientation=e.orientation,
    )  # fmt: skip
    return dataclasses.replace(model, hysteresis=fresh, sees=sees)


def _with_thermal_start(model, init, u0=None):
    th = model.thermal
    new = dataclasses.replace(th, init=init, u0=None if u0 is None else jnp.asarray(float(u0)))
    return dataclasses.replace(model, thermal=new)


def _weighted_sse(model, data, weights):
    total = 0.0
    for (u, y, d), w in zip(data, weights):
        r = np.asarray(model.simulate(jnp.asarray(u), d)) - y
        total += float(np.sum(w * r * r))
    return total if np.isfinite(total) else np.inf


def screen_start(
    start,
    data,
    weights,
    *,
    orientation="auto",
    thermal_start="auto",
    sees="auto",
    k1_grid=16,
    val_weights=None,
    progress=False,
):
    """Best profiled start over output orientation, hysteresis input and thermal start candidates.

    ``data``/``weights`` as for `fit` (the weights select the training samples).  ``orientation``:
    "auto", "rises" or "falls"; ``sees`` (cascades): "auto", "voltage" or "heat" (see `Cascade`);
    ``thermal_start`` (cascades): "auto", "steady", "cold" or "fitted".  Stage 1 screens orientation x
    sees with the steady and cold starts; stage 2 adds warm and hot starts for the best of stage 1
    (a record may start hot with the power off, where "steady" equals "cold").  With "auto"/"fitted"
    the winner's start becomes a fitted initial effective voltage ``u0`` (one record only).
    Returns ``(model, table, info)``: the profiled start, one row per candidate and the winner's
    initialiser info (k1 profile).

    ``val_weights`` (held-out samples, optional): the hysteresis input is then chosen by the
    held-out error of each input's best candidate, not by training loss.  Measured on independent
    records, the two inputs fit training data about equally well and differ most where held-out
    data leaves the trained branches, which the training loss cannot see.
    """
    if orientation not in ("auto", "rises", "falls"):
        raise UserInputError(f"orientation must be auto, rises or falls, got {orientation!r}")
    if thermal_start not in ("auto", "steady", "cold", "fitted"):
        raise UserInputError(f"thermal start must be auto, steady, cold or fitted, got {thermal_start!r}")
    if sees not in ("auto", "voltage", "heat"):
        raise UserInputError(f"hysteresis input must be auto, voltage or heat, got {sees!r}")
    data = as_fit_data(data)
    signs = {"auto": (1, -1), "rises": (1,), "falls": (-1,)}[orientation]
    cascade = isinstance(start, Cascade)
    u_hi = max(float(np.max(np.asarray(d[0]))) for d in data) if cascade else None
    if cascade:
        inputs = ("voltage", "heat") if sees == "auto" else (sees,)
        first = {"auto": ("steady", "cold"), "fitted": ("steady", "cold"), "steady": ("steady",), "cold": ("cold",)}
        first = first[thermal_start]
    else:
        inputs, first = (None,), (None,)
    say = (lambda msg: print(msg, file=sys.stderr)) if progress else (lambda msg: None)
    table, best, best_by_input = [], None, {}

    def candidate(sign, inp, th):
        nonlocal best
        m = _with_orientation(start, sign)
        if inp is not None:
            m = _with_sees(m, inp, u_hi)
        if th == "steady":
            m = _with_thermal_start(m, "steady")
        elif th is not None:
            m = _with_thermal_start(m, "given", _START_FRACTION[th] * u_hi)
        t0 = time.perf_counter()
        row = {"orientation": sign, "sees": inp, "thermal_start": th}
        try:
            res = fit(m, data, weights=weights, solver=None, k1_grid=k1_grid)
        except UserInputError as exc:
            table.append({**row, "loss": None, "error": str(exc)})
            return
        table.append({**row, "loss": float(res.loss), "seconds": time.perf_counter() - t0})
        desc = f"output {'rises' if sign > 0 else 'falls'}" + (f", hysteresis sees {inp}, thermal start {th}" if inp else "")
        say(f"  start candidate: {desc}: profiled loss {res.loss:.6g}")
        if best is None or res.loss < best[0]:
            best = (res.loss, res.model, (sign, inp, th), res.info)
        if inp not in best_by_input or res.loss < best_by_input[inp][0]:
            best_by_input[inp] = (res.loss, res.model, (sign, inp, th), res.info)

    for sign in signs:
        for inp in inputs:
            for th in first:
                candidate(sign, inp, th)
    if best is None:
        raise UserInputError("no start candidate gave a finite model output; check the input units and range")
    if val_weights is not None and len(best_by_input) > 1:
        val_weights = [np.asarray(w, dtype=np.float64) for w in val_weights]
        if sum(float(np.sum(w)) for w in val_weights) > 0:
            scores = {inp: _weighted_sse(c[1], data, val_weights) for inp, c in best_by_input.items()}
            chosen = min(scores, key=lambda k: scores[k])
            best = best_by_input[chosen]
            for row in table:
                row["heldout_sse_of_input"] = scores.get(row["sees"])
            say(f"  hysteresis input chosen on held-out error: {chosen} ({', '.join(f'{k} {v:.4g}' for k, v in scores.items())})")
    if cascade and thermal_start in ("auto", "fitted"):
        sign, inp, _ = best[2]
        for th in ("warm", "hot"):
            candidate(sign, inp, th)
    _, model, (_, _, th), info = best
    if cascade and thermal_start in ("auto", "fitted") and len(data) == 1:
        # free initial effective voltage from the best start: the refinement moves it to the record's own start
        u_first = float(np.asarray(data[0][0])[0])
        u0 = max(u_first, COLD_FRACTION * u_hi) if th == "steady" else _START_FRACTION[th] * u_hi
        model = _with_thermal_start(model, "given", u0)
    return model, table, info
