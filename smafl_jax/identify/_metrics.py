"""Error measures: eq. (3) error ratio, eq. (8) mean error, RMSE, max error."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from .. import _config  # noqa: F401

__all__ = [
    "error_ratio",
    "e_mean",
    "rmse",
    "max_abs_error",
    "mean_abs_error",
    "metrics",
    "noise_floor",
    "noise_floor_note",
    "measured_samples",
    "NOISE_FLOOR_WARN",
    "ABOVE_NOISE",
]

#: A training RMSE above this many output-noise SDs: the model leaves structure in its own training samples.  The
#: estimate is within 0.8-1.25x the true SD on 167 of 168 records of the independent plant (7 drive families, 5-100 Hz;
#: .notes/session28/noise_scale_check.py), so 2x is misfit, not an estimate's scatter.
NOISE_FLOOR_WARN = 2.0
NOISE_METHOD = (
    "1.4826 MAD of the output's second differences / sqrt(6), per record (white-noise scale; a filtered sensor reads lower)"
)
#: Added to `NOISE_METHOD` when a resampled record's gaps held interpolated samples.
INTERPOLATED_RULE = (
    "; the samples a resampling interpolated across gaps are left out (a second difference only where none of its three "
    "samples lies inside a bridged gap: a straight line has no noise); the grid samples between measured stamps closer "
    "than a gap are interpolations too, and on jittered stamps they still read the noise up to ~1.5x low"
)
#: Added to `NOISE_METHOD` when a resampled record's noise was estimated on its time stamps as read (`Record.as_read`).
AS_READ_RULE = (
    "; a resampled record's noise is estimated on its output as read, on the file's own time stamps within the record's "
    "span, from each sample's distance to the line through its neighbours (steps of 1.5 sample times or more left out): "
    "interpolating between jittered stamps averages neighbouring samples, and the resampled grid read the noise "
    "0.6-0.9x low on jittered records"
)


def _pair(y, yhat):
    y = jnp.asarray(y, dtype=jnp.float64)
    yhat = jnp.asarray(yhat, dtype=jnp.float64)
    if y.shape != yhat.shape:
        raise ValueError(f"measured and model outputs differ in shape: {y.shape} vs {yhat.shape}")
    return y, yhat


def error_ratio(y: ArrayLike, yhat: ArrayLike) -> jax.Array:
    """Eq. (3): ``max|y - yhat| / (max y - min y) * 100`` in percent of the measured output range."""
    y, yhat = _pair(y, yhat)
    return jnp.max(jnp.abs(y - yhat)) / (jnp.max(y) - jnp.min(y)) * 100.0


def e_mean(y_ref: ArrayLike, y: ArrayLike) -> jax.Array:
    """Eq. (8): mean absolute tracking error ``sum |y_d - y| / N``."""
    y_ref, y = _pair(y_ref, y)
    return jnp.mean(jnp.abs(y_ref - y))


mean_abs_error = e_mean


def rmse(y: ArrayLike, yhat: ArrayLike) -> jax.Array:
    y, yhat = _pair(y, yhat)
    return jnp.sqrt(jnp.mean((y - yhat) ** 2))


def max_abs_error(y: ArrayLike, yhat: ArrayLike) -> jax.Array:
    y, yhat = _pair(y, yhat)
    return jnp.max(jnp.abs(y - yhat))


def metrics(y: ArrayLike, yhat: ArrayLike) -> dict[str, float]:
    """All fit metrics as plain floats: ``rmse``, ``e_r_percent``, ``max_abs_error``, ``mean_abs_error``."""
    y = np.asarray(y, dtype=np.float64)
    yhat = np.asarray(yhat, dtype=np.float64)
    if y.shape != yhat.shape:
        raise ValueError(f"measured and model outputs differ in shape: {y.shape} vs {yhat.shape}")
    if y.size == 0:
        raise ValueError("metrics need at least one sample")
    err = y - yhat
    span = float(np.max(y) - np.min(y))
    return {
        "rmse": float(np.sqrt(np.mean(err**2))),
        "e_r_percent": float(np.max(np.abs(err)) / span * 100.0) if span > 0 else float("nan"),
        "max_abs_error": float(np.max(np.abs(err))),
        "mean_abs_error": float(np.mean(np.abs(err))),
        "n_samples": int(y.size),
    }


def measured_samples(record) -> np.ndarray:
    """Boolean mask of a record's samples that are not interpolated across a gap its resampling bridged
    (`Record.measured`; all True for an object without ``gaps``)."""
    if hasattr(record, "measured"):
        return np.asarray(record.measured, bool)
    return np.ones(np.asarray(record.time).shape[0], bool)


def _is_record(item) -> bool:
    return hasattr(item, "y") and hasattr(item, "time")


def _as_read_output(record) -> tuple[np.ndarray, np.ndarray] | None:
    """A resampled record's time stamps and output as read, within the record's span (`Record.as_read`), or None when
    it has none or its ``y`` is no longer the interpolation of them (replaced since: the grid is then all there is)."""
    raw = getattr(record, "as_read", None)
    if raw is None or raw.y is None:
        return None
    t, y = np.asarray(record.time, dtype=np.float64), np.asarray(record.y, dtype=np.float64)
    t_raw, y_raw = np.asarray(raw.time, dtype=np.float64), np.asarray(raw.y, dtype=np.float64)
    from ..data.record import STAMP_RTOL

    tol = STAMP_RTOL * float(record.dt)  # a stamp written with fewer digits than the grid's arithmetic is on it
    keep = (t_raw >= t[0] - tol) & (t_raw <= t[-1] + tol)
    if keep.sum() < 3 or y.shape != t.shape:
        return None
    scale = float(np.nanmax(np.abs(y_raw))) if np.any(np.isfinite(y_raw)) else 1.0
    if not np.allclose(np.interp(t, t_raw, y_raw), y, rtol=1e-9, atol=1e-12 * max(scale, 1e-300), equal_nan=True):
        return None
    return t_raw[keep], y_raw[keep]


def noise_floor(outputs, **scored: dict | None) -> dict:
    """The output's noise SD estimated from the measured outputs alone, and each scored RMSE in units of it.

    Why: an RMSE in mm says nothing about whether a fit is done; the same RMSE over the sensor's noise says it (1x: the
    model explains everything but the noise).  ``outputs``: one measured output per record (pooled by samples), each an
    array or a `Record` (its ``y``; the samples interpolated across resampling gaps, `measured_samples`, are left out
    of the estimate: a record resampled from bursts had 26 % of them and read 2x low); ``scored``: metric dicts by name
    (``train=..., validation=...``), each giving ``<name>_ratio`` = its RMSE / SD (None when absent, or when the output
    is quantised so coarsely that the estimate is 0).
    """
    from ..data.checks import noise_scale, noise_scale_on_stamps
    from ..data.record import GAP_STEPS

    if _is_record(outputs) or (isinstance(outputs, (np.ndarray, jax.Array)) and np.ndim(outputs) == 1):
        outputs = [outputs]  # one record or one output array, not a list of them
    sds, n, n_left, n_as_read = [], [], 0, 0
    for i, item in enumerate(outputs):
        if _is_record(item):  # a Record: its gaps say which samples were filled in
            if item.y is None:
                raise ValueError(f"noise_floor: record {item.name!r} has no output")
            if (raw := _as_read_output(item)) is not None:
                # a step of 1.5 sample times or more misses a sample: the signal moves across it
                sds.append(noise_scale_on_stamps(*raw, max_step=GAP_STEPS * float(item.dt)))
                n.append(int(np.isfinite(raw[1]).sum()))
                n_as_read += 1
                continue
            y, ok = np.asarray(item.y, dtype=np.float64), measured_samples(item)
            n_left += int(ok.size - ok.sum())
        else:
            y = np.asarray(item, dtype=np.float64)
            if y.ndim != 1:
                raise ValueError(
                    f"noise_floor: output {i} must be a 1-D array (one sample per time step) or a Record, got shape {y.shape}"
                )
            ok = np.ones(y.shape, bool)
        ok = ok & np.isfinite(y)  # blank / NaN cells: no second difference across them either
        sds.append(noise_scale(np.where(ok, y, 0.0), None if ok.all() else ok))
        n.append(int(ok.sum()))  # each record weighs by the samples its estimate saw
    if not sds:
        raise ValueError("noise_floor needs at least one output record")
    n = np.array(n, dtype=np.float64)
    sd = float(np.sqrt(np.sum(n * np.square(sds)) / np.sum(n))) if np.sum(n) > 0 else 0.0
    method = NOISE_METHOD + (INTERPOLATED_RULE if n_left else "") + (AS_READ_RULE if n_as_read else "")
    out: dict = {"sd": sd, "method": method}
    if n_left:
        out["n_interpolated_left_out"] = n_left
    if n_as_read:
        out["n_records_on_stamps_as_read"] = n_as_read
    if len(sds) > 1:
        out["per_record_sd"] = [float(x) for x in sds]
    for name, m in scored.items():
        ok = m is not None and sd > 0 and np.isfinite(m.get("rmse", np.nan))
        out[f"{name}_ratio"] = float(m["rmse"] / sd) if ok else None
    return out


#: Start of the note (printed as a warning by `smafl fit`) when the fit stays far above the output's noise on its training.
ABOVE_NOISE = "above the noise floor:"


def noise_floor_note(noise: dict) -> str | None:
    """The note for a fit whose training RMSE is more than `NOISE_FLOOR_WARN` output-noise SDs, else None."""
    r = noise.get("train_ratio")
    if r is None or r <= NOISE_FLOOR_WARN:
        return None
    return (
        f"{ABOVE_NOISE} training RMSE {r:.3g}x the output's noise SD ({noise['sd']:.4g}, estimated from the record's "
        "sample-to-sample scatter): the model leaves structure in its own training samples, which a new run will see too "
        "(try another --model, or `smafl diagnose` for an effect the model lacks)"
    )
