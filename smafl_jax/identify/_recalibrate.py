"""Re-anchoring a fitted model on a short calibration segment at the start of a new run.

A model fitted on one run of a rig often sits beside the next run by a constant: a thermocouple that
reads a few degrees off, a supply that delivers a slightly different voltage, a length sensor zeroed
elsewhere.  `Recalibrated` wraps any model with those three numbers,

    y(k) = model.simulate(input_gain * u + input_offset, dt)(k) + output_offset,

and `recalibrate` fits 1-3 of them by least squares on a user-chosen segment of the new record only
(the model runs from t = 0 through the segment, so the operators' memory is the one the new run
builds).  Only what follows the segment is a fair score of the re-anchored model
(`after_segment_metrics`).

Fitting: the output offset enters linearly, so it is profiled out in closed form (the mean residual
over the segment); the input gain and offset are first screened on a small grid (one `vmap`, which
guards against the flat or multimodal loss a play operator or a crisp relay gives in the input), then
refined jointly with the output offset by optimistix Levenberg-Marquardt.

The input parameters are bounded to what a run-to-run drift can be (default: gain within a factor 1.5
of its start, input offset within 25 % of the record's input span), by ``gain = g0 exp(log(1.5) tanh p)``
and ``offset = a0 + B tanh q``: measured on the NiTi records, an unbounded fit on a short segment found
gains of 0.1 and offsets of -125 degC that matched the segment and wrecked the rest of the run.  A value
that ends at its bound is named in ``info["at_bound"]`` (the segment does not pin it down).

What the calibration can check itself is said in ``info["warnings"]`` (and logged): a value at its bound, a
refinement that stopped without converging, and a re-anchored model that fits its own segment no better than the
raw one (`NOT_IMPROVED`).  Whether it helps after the segment only the rest of the run can tell
(`after_segment_metrics`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from numpy.typing import ArrayLike

from .. import _config  # noqa: F401
from .._errors import UserInputError
from .._io import register_model
from ..models._constraints import parameter, positive
from ..models._hysteresis import record_model
from ..models._simulate import simulate

__all__ = [
    "Recalibrated",
    "recalibrate",
    "segment_indices",
    "after_segment_metrics",
    "CALIBRATION_PARAMETERS",
    "NOT_IMPROVED",
]

logger = logging.getLogger(__name__)

#: The parameters `recalibrate` can fit, in this order.
CALIBRATION_PARAMETERS = ("input_gain", "input_offset", "output_offset")
#: A segment must hold at least this many samples per fitted parameter.
SAMPLES_PER_PARAMETER = 5
#: Screening grid: input gains (ratios around 1) and input offsets (fractions of the input offset bound).
_GAIN_GRID = np.geomspace(0.8, 1.25, 5)
_OFFSET_GRID = np.linspace(-0.8, 0.8, 9)
#: Default bounds: the gain within this factor of its start, the input offset within this fraction of the input span.
MAX_GAIN_RATIO = 1.5
MAX_INPUT_OFFSET_FRACTION = 0.25
#: A fitted value this close to its bound (fraction of the half-width, in the tanh coordinate) counts as at the bound.
_AT_BOUND = 0.99
#: Start of the warning when the re-anchored model fits its own calibration segment no better than the raw model.
NOT_IMPROVED = "calibration did not help on its own segment:"


@register_model
class Recalibrated(eqx.Module):
    """A fitted model re-anchored on a new run: ``model(input_gain * u + input_offset) + output_offset``.

    Saved and loaded like any other model (`save_model` / `load_model`); the wrapped model keeps its
    own initial-state rule.
    """

    model: eqx.Module
    input_gain: jax.Array = positive(default=1.0)
    input_offset: jax.Array = parameter(default=0.0)
    output_offset: jax.Array = parameter(default=0.0)

    def model_input(self, u):
        """The input the wrapped model sees: ``input_gain * u + input_offset``."""
        return self.input_gain * u + self.input_offset

    def simulate(self, u, dt):
        """Re-anchored output for input record ``u`` sampled every ``dt`` seconds (required, as `sj.simulate` asks of
        every model that is not a hysteresis model on its own)."""
        return self.model.simulate(self.model_input(u), dt) + self.output_offset

    def __call__(self, u, dt):
        return self.simulate(u, dt)

    def for_record(self, i: int) -> Recalibrated:
        """The wrapped model as it starts record ``i`` of a joint fit."""
        return eqx.tree_at(lambda m: m.model, self, record_model(self.model, i))

    def with_method(self, method: str) -> Recalibrated:
        """Copy with the wrapped model evaluated by ``method`` (see `model_with_method`)."""
        from ..models._operators import model_with_method

        return eqx.tree_at(lambda m: m.model, self, model_with_method(self.model, method))

    def calibration(self) -> dict:
        """The three numbers as plain floats."""
        return {name: float(getattr(self, name)) for name in CALIBRATION_PARAMETERS}


def _fmt_time(t: float) -> str:
    return f"{t:.6g} s"


def segment_indices(segment, n: int, dt: float, t0: float = 0.0) -> tuple[int, int]:
    """``[i0, i1)`` sample indices of ``segment`` in a record of ``n`` samples starting at time ``t0``.

    ``segment`` is ``(start_s, end_s)`` in the record's time units (half-open: samples with
    ``start <= t < end``; ``start=None`` = the record's first sample) or a `slice` of sample indices.
    `UserInputError` when the segment is reversed, outside the record or holds no sample.
    """
    if n < 1:
        raise UserInputError("calibration: the record is empty")
    t_last = t0 + (n - 1) * dt
    if isinstance(segment, slice):
        if segment.step not in (None, 1):
            raise UserInputError(f"calibration segment {segment}: a step is not allowed")
        i0 = 0 if segment.start is None else int(segment.start)
        i1 = n if segment.stop is None else int(segment.stop)
        if i0 < 0 or i1 > n:
            raise UserInputError(f"calibration segment samples [{i0}, {i1}) lie outside the record (samples 0..{n - 1})")
        if i0 >= i1:
            raise UserInputError(f"calibration segment samples [{i0}, {i1}): the start must come before the end")
        return i0, i1
    if not (isinstance(segment, Sequence) and len(segment) == 2):
        raise UserInputError(f"calibration segment must be (start_s, end_s) or a slice of samples, got {segment!r}")
    start = t0 if segment[0] is None else float(segment[0])
    end = float(segment[1])
    if not (math.isfinite(start) and math.isfinite(end)):
        raise UserInputError(f"calibration segment {start:g}:{end:g}: start and end must be finite")
    if start >= end:
        raise UserInputError(f"calibration segment {start:g}:{end:g} s: the start must come before the end")
    eps = 1e-9 * max(dt, abs(t0), abs(t_last))
    if t0 - dt - eps <= start < t0:
        # a start up to one sample time before the first stamp (a logger writing its first row at t = dt; the README's
        # `--calibrate 0:30`) means the record's start, as an end up to one sample after the last means its end
        start = t0
    if start < t0 - eps or start > t_last + eps:
        raise UserInputError(
            f"calibration segment {start:g}:{end:g} s starts outside the record, which runs from {_fmt_time(t0)} to {_fmt_time(t_last)}"
        )
    if end > t_last + dt + eps:
        raise UserInputError(
            f"calibration segment {start:g}:{end:g} s ends after the record, which runs from {_fmt_time(t0)} to {_fmt_time(t_last)}"
        )
    tol = 1e-9
    i0 = max(0, math.ceil((start - t0) / dt - tol))
    i1 = min(n, math.ceil((end - t0) / dt - tol))
    if i1 <= i0:
        raise UserInputError(
            f"calibration segment {start:g}:{end:g} s holds no sample (the record is sampled every {dt:g} s from {_fmt_time(t0)})"
        )
    return i0, i1


def _check_fit_names(fit) -> tuple[str, ...]:
    if isinstance(fit, str):
        fit = (fit,)
    names = tuple(fit)
    if not names:
        raise UserInputError(f"calibration: choose at least one of {list(CALIBRATION_PARAMETERS)} to fit")
    unknown = [n for n in names if n not in CALIBRATION_PARAMETERS]
    if unknown:
        raise UserInputError(f"calibration: unknown parameter(s) {unknown}; choose from {list(CALIBRATION_PARAMETERS)}")
    if len(set(names)) != len(names):
        raise UserInputError(f"calibration: parameter named twice in {list(names)}")
    return tuple(n for n in CALIBRATION_PARAMETERS if n in names)


def _span(x) -> float:
    s = float(np.max(x) - np.min(x)) if np.size(x) else 0.0
    return s if s > 0 else max(float(np.max(np.abs(x))) if np.size(x) else 0.0, 1.0)


@eqx.filter_jit
def _grid_losses(model, gains, offsets, u, y, w, dt, fit_out, c_fixed):
    """Segment loss of every (gain, offset) candidate, the output offset profiled when it is fitted."""

    def one(g, o):
        yh = model.simulate(g * u + o, dt)
        r = y - yh
        c = jnp.where(fit_out, jnp.sum(w * r) / jnp.sum(w), c_fixed)
        loss = jnp.sum(w * (r - c) ** 2)
        return jnp.where(jnp.isfinite(loss), loss, jnp.inf), c

    return jax.vmap(one)(gains, offsets)


@eqx.filter_jit
def _solve(model, p0, args, max_steps):
    def residuals(p, a):
        u, y, w, dt, fixed, log_ratio, bound, sy = a
        g = fixed[0] * jnp.exp(log_ratio * jnp.tanh(p["input_gain"])) if "input_gain" in p else fixed[0]
        o = fixed[1] + bound * jnp.tanh(p["input_offset"]) if "input_offset" in p else fixed[1]
        c = sy * p["output_offset"] if "output_offset" in p else fixed[2]
        return w * (model.simulate(g * u + o, dt) + c - y) / sy

    solver = optx.LevenbergMarquardt(rtol=1e-12, atol=1e-12)
    sol = optx.least_squares(residuals, solver, p0, args, max_steps=max_steps, throw=False)
    r = residuals(sol.value, args)
    return sol.value, jnp.sum(r**2), sol.stats["num_steps"], sol.result == optx.RESULTS.successful


def recalibrate(
    model: eqx.Module,
    u: ArrayLike,
    y: ArrayLike,
    dt: float,
    segment: tuple[float, float] | slice,
    *,
    fit: Sequence[str] | str = CALIBRATION_PARAMETERS,
    t0: float = 0.0,
    max_steps: int = 200,
    max_gain_ratio: float = MAX_GAIN_RATIO,
    max_input_offset: float | None = None,
    log_warnings: bool = True,
) -> tuple[Recalibrated, dict]:
    """Re-anchor ``model`` on ``segment`` of a new record ``(u, y)``: ``(Recalibrated model, info)``.

    ``segment``: ``(start_s, end_s)`` in the record's time (sample k at ``t0 + k dt``; half-open) or a
    `slice` of samples.  ``fit``: which of ``input_gain``, ``input_offset``, ``output_offset`` to fit
    (the others stay at 1 / 0 / 0, or at their values when ``model`` is already `Recalibrated`).
    Only the segment enters the loss; the model runs from the record's first sample through it.
    Bounds (drift, not a refit): the gain stays within ``max_gain_ratio`` of its start, the input
    offset within ``max_input_offset`` of its start (default: 25 % of the input span of ``u``).
    ``info``: the fitted values, the segment (seconds and samples), its RMSE before and after
    (``segment_improved``: after < before), the first sample after the segment (``scored_from_sample``), where a fair
    score starts, and ``warnings`` (sentences; logged unless ``log_warnings=False``, for a caller that reports them
    itself): a value at its bound, a refinement that did not converge, a segment the re-anchoring did not improve.
    """
    names = _check_fit_names(fit)
    if not (math.isfinite(max_gain_ratio) and max_gain_ratio > 1):
        raise UserInputError(f"calibration: max_gain_ratio must be > 1, got {max_gain_ratio}")
    if max_input_offset is not None and not (math.isfinite(max_input_offset) and max_input_offset > 0):
        raise UserInputError(f"calibration: max_input_offset must be > 0, got {max_input_offset}")
    u = np.asarray(u, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if u.ndim != 1 or u.shape != y.shape:
        raise UserInputError(f"calibration: input and output must be 1-D of equal length, got {u.shape} and {y.shape}")
    dt = float(dt)
    if not (math.isfinite(dt) and dt > 0):
        raise UserInputError(f"calibration: sample time must be > 0, got {dt}")
    i0, i1 = segment_indices(segment, u.shape[0], dt, t0)
    n_seg = i1 - i0
    need = SAMPLES_PER_PARAMETER * len(names)
    if n_seg < need:
        raise UserInputError(
            f"calibration segment holds {n_seg} sample(s) ({_fmt_time(t0 + i0 * dt)} to {_fmt_time(t0 + (i1 - 1) * dt)}); "
            f"fitting {len(names)} parameter(s) ({', '.join(names)}) needs at least {need}: choose a longer segment"
        )
    if not (np.all(np.isfinite(u[:i1])) and np.all(np.isfinite(y[i0:i1]))):
        raise UserInputError("calibration: non-finite input or output values up to the end of the segment")

    if isinstance(model, Recalibrated):
        start = model.calibration()
        inner = model.model
    else:
        start = {"input_gain": 1.0, "input_offset": 0.0, "output_offset": 0.0}
        inner = model
    uh = jnp.asarray(u[:i1])
    yh = jnp.asarray(y[:i1])
    w = np.zeros(i1)
    w[i0:] = 1.0
    w = jnp.asarray(w)
    dtj = jnp.asarray(dt)

    def seg_rmse(g, o, c):
        pred = np.asarray(simulate(inner, g * uh + o, dt)) + c
        return float(np.sqrt(np.mean((pred[i0:] - y[i0:i1]) ** 2)))

    rmse_before = seg_rmse(start["input_gain"], start["input_offset"], start["output_offset"])
    bound = MAX_INPUT_OFFSET_FRACTION * _span(u) if max_input_offset is None else float(max_input_offset)
    log_ratio = math.log(max_gain_ratio)
    sy = _span(y[i0:i1])

    # 1. screening grid over the input parameters (the output offset profiled in closed form)
    gains = start["input_gain"] * (
        np.clip(_GAIN_GRID, 1 / max_gain_ratio, max_gain_ratio) if "input_gain" in names else np.ones(1)
    )
    offs = start["input_offset"] + (bound * _OFFSET_GRID if "input_offset" in names else np.zeros(1))
    g_grid, o_grid = (a.ravel() for a in np.meshgrid(gains, offs, indexing="ij"))
    fit_out = "output_offset" in names
    losses, cs = _grid_losses(
        inner, jnp.asarray(g_grid), jnp.asarray(o_grid), uh, yh, w, dtj, jnp.asarray(fit_out), jnp.asarray(start["output_offset"])
    )
    losses, cs = np.asarray(losses), np.asarray(cs)
    if not np.any(np.isfinite(losses)):
        raise UserInputError("calibration: the model gives non-finite output on the segment for every screened input gain/offset")
    k = int(np.argmin(losses))
    best = {"input_gain": float(g_grid[k]), "input_offset": float(o_grid[k]), "output_offset": float(cs[k])}
    best_loss = float(losses[k])
    n_steps, converged, method = 0, True, "closed form (mean residual)" if names == ("output_offset",) else "grid"
    lm_kept = False

    # 2. joint Levenberg-Marquardt refinement from the best grid point (not needed for the output offset alone)
    if names != ("output_offset",) and max_steps > 0:
        p0 = {}
        if "input_gain" in names:
            x = math.log(best["input_gain"] / start["input_gain"]) / log_ratio
            p0["input_gain"] = jnp.asarray(math.atanh(min(max(x, -_AT_BOUND), _AT_BOUND)))
        if "input_offset" in names:
            x = (best["input_offset"] - start["input_offset"]) / bound
            p0["input_offset"] = jnp.asarray(math.atanh(min(max(x, -_AT_BOUND), _AT_BOUND)))
        if fit_out:
            p0["output_offset"] = jnp.asarray(best["output_offset"] / sy)
        fixed = jnp.asarray([start["input_gain"], start["input_offset"], start["output_offset"]])
        args = (uh, yh, w, dtj, fixed, jnp.asarray(log_ratio), jnp.asarray(bound), jnp.asarray(sy))
        p, loss, steps, ok = _solve(inner, p0, args, int(max_steps))
        loss = float(loss) * sy * sy
        cand = {
            "input_gain": start["input_gain"] * math.exp(log_ratio * math.tanh(float(p["input_gain"])))
            if "input_gain" in p
            else start["input_gain"],
            "input_offset": start["input_offset"] + bound * math.tanh(float(p["input_offset"]))
            if "input_offset" in p
            else start["input_offset"],
            "output_offset": sy * float(p["output_offset"]) if "output_offset" in p else best["output_offset"],
        }
        n_steps, converged = int(steps), bool(ok)
        if math.isfinite(loss) and all(math.isfinite(v) for v in cand.values()) and loss <= best_loss:
            best, best_loss, method, lm_kept = cand, loss, "grid + Levenberg-Marquardt", True
        else:
            logger.info(
                "calibration: the Levenberg-Marquardt refinement did not improve on the grid (loss %g vs %g)", loss, best_loss
            )
            method = "grid (Levenberg-Marquardt did not improve on it)"

    out = Recalibrated(inner, best["input_gain"], best["input_offset"], best["output_offset"])
    at_bound = []
    if "input_gain" in names and abs(math.log(best["input_gain"] / start["input_gain"])) >= _AT_BOUND * log_ratio:
        at_bound.append("input_gain")
    if "input_offset" in names and abs(best["input_offset"] - start["input_offset"]) >= _AT_BOUND * bound:
        at_bound.append("input_offset")
    warnings = []
    if at_bound:
        warnings.append(
            f"calibration: {', '.join(at_bound)} ended at its bound (gain ratio {max_gain_ratio:g}, input offset "
            f"+-{bound:.5g}): the segment does not determine it; a longer segment or the output offset alone (Python: "
            "fit='output_offset'; CLI: --calibrate-fit output_offset) is safer"
        )
    if not converged:
        warnings.append(
            f"calibration: the Levenberg-Marquardt refinement stopped after {n_steps} steps (limit {int(max_steps)}) without "
            "converging: "
            + (
                "the values are the last it reached, not a settled least-squares optimum of the segment"
                if lm_kept
                else "the screened grid point is kept (a coarse value)"
            )
            + (
                f" ({', '.join(at_bound)} at its bound keeps the solver walking toward it)"
                if at_bound
                else "; a longer segment or fewer parameters is safer"
            )
        )
    rmse_after = seg_rmse(best["input_gain"], best["input_offset"], best["output_offset"])
    # the grid holds the start, so the fit cannot be worse on its segment by construction; no better means it found
    # nothing to correct there (or the model gives the segment no handle on the parameters): say so, not silently
    improved = bool(rmse_after < rmse_before)
    if not improved:
        warnings.append(
            f"{NOT_IMPROVED} the re-anchored model fits the calibration segment no better than the raw model (segment RMSE "
            f"{rmse_before:.4g} -> {rmse_after:.4g}), so the segment gives no evidence that it helps on the rest of the run"
        )
    if log_warnings:
        for text in warnings:
            logger.warning(text)
    info = {
        "fitted": list(names),
        **{name: best[name] for name in CALIBRATION_PARAMETERS},
        "segment": {
            "start_s": t0 + i0 * dt,
            "end_s": t0 + i1 * dt,
            "start_sample": i0,
            "end_sample": i1,
            "n_samples": n_seg,
        },
        "segment_rmse_before": rmse_before,
        "segment_rmse_after": rmse_after,
        "segment_improved": improved,
        "scored_from_sample": i1,
        "scored_from_s": t0 + i1 * dt,
        "bounds": {"input_gain_ratio": max_gain_ratio, "input_offset": bound},
        "at_bound": at_bound,
        "method": method,
        "n_steps": n_steps,
        "converged": converged,
        "warnings": warnings,
    }
    logger.info("calibration on samples [%d, %d): %s, segment RMSE %.4g -> %.4g", i0, i1, best, rmse_before, rmse_after)
    return out, info


def after_segment_metrics(y, y_raw, y_recalibrated, scored_from_sample: int) -> dict:
    """Metrics (`metrics`) of the raw and the re-anchored output on the samples after the calibration segment."""
    from ._metrics import metrics

    y = np.asarray(y, dtype=np.float64)
    k = int(scored_from_sample)
    if k >= y.shape[0]:
        raise UserInputError(
            f"nothing to score: the calibration segment ends at sample {k} and the record has {y.shape[0]} samples"
        )
    return {
        "scored_from_sample": k,
        "raw": metrics(y[k:], np.asarray(y_raw)[k:]),
        "recalibrated": metrics(y[k:], np.asarray(y_recalibrated)[k:]),
    }
