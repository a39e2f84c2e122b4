"""Jitted public entry points for running any model on an input record."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.typing import ArrayLike

from .. import _config  # noqa: F401

__all__ = ["simulate", "simulate_batch"]


def _checked(u, dt):
    # Value checks that need the data: they run inside the compiled function
    # (equinox.error_if), so a bad value in a jitted sweep is caught too.
    u = eqx.error_if(u, ~jnp.all(jnp.isfinite(u)), "input record contains NaN or inf")
    dt = eqx.error_if(dt, ~(dt > 0), "sample time dt must be > 0")
    return u, dt


@eqx.filter_jit
def _simulate(model, u, dt):
    u, dt = _checked(u, dt)
    return model.simulate(u, dt)


@eqx.filter_jit
def _simulate_batch(model, u, dt):
    u, dt = _checked(u, dt)
    return jax.vmap(lambda x: model.simulate(x, dt))(u)


def _as_inputs(u, dt, ndim):
    u = jnp.asarray(u, dtype=jnp.float64)
    if u.ndim != ndim:
        raise ValueError(f"input must be {ndim}-D, got shape {u.shape}")
    if u.shape[-1] < 2:
        raise ValueError(f"input record needs at least 2 samples, got {u.shape[-1]}")
    # dt goes in as an array so a new sample time never triggers a recompile.
    dt = jnp.asarray(1.0 if dt is None else dt, dtype=jnp.float64)
    if dt.ndim != 0:
        raise ValueError(f"dt must be a scalar, got shape {dt.shape}")
    return u, dt


def simulate(model: eqx.Module, u: ArrayLike, dt: ArrayLike | None = None) -> jax.Array:
    """Model output for a 1-D input record ``u`` sampled every ``dt`` seconds (compiled once per shape)."""
    u, dt = _as_inputs(u, dt, 1)
    return _simulate(model, u, dt)


def simulate_batch(model: eqx.Module, u: ArrayLike, dt: ArrayLike | None = None) -> jax.Array:
    """Model outputs ``(B, T)`` for a batch of input records ``(B, T)`` (one `vmap`, one compile)."""
    u, dt = _as_inputs(u, dt, 2)
    return _simulate_batch(model, u, dt)
