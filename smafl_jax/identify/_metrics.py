"""Error measures: eq. (3) error ratio, eq. (8) mean error, RMSE, max error."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from .. import _config  # noqa: F401

__all__ = ["error_ratio", "e_mean", "rmse", "max_abs_error", "mean_abs_error", "metrics"]


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
