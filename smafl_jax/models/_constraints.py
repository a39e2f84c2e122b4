"""Positivity by reparametrisation.

A model field declared with `positive()` holds a physical value > 0.  Fitting
and sampling work on an *unconstrained* copy of the model in which each such
field holds ``softplus^{-1}(value)``; `constrain` maps back inside the loss, so
optimisers never see a bound and the MCMC density picks up `log_jacobian`.
"""

from __future__ import annotations

import dataclasses
from typing import Any, TypeVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import _config  # noqa: F401

__all__ = [
    "positive",
    "parameter",
    "as_float_array",
    "constrain",
    "unconstrain",
    "log_jacobian",
    "positive_mask",
    "POSITIVE_FLOOR",
]

#: Smallest value `unconstrain` maps; exact zeros (e.g. from NNLS) become this.
POSITIVE_FLOOR = 1e-10


def as_float_array(x):
    """Field converter: numbers become float64 arrays, so they are parameters, not static constants.

    Without it ``JouleThermal(0.05, 0.04)`` would hold Python floats, which
    `equinox` treats as non-array leaves that no fit or sampler ever moves.
    Weakly typed arrays (``jnp.full(n, 0.5)``) become strongly typed: `jit` keys on the weak type, so a model
    whose field was built one way or the other compiled the same fit twice (measured: 5-6 s per LM solve).
    """
    if (
        x is None
        or isinstance(x, jax.core.Tracer)
        or not isinstance(x, (int, float, list, tuple, np.ndarray, np.generic, jax.Array))
    ):
        return x
    if isinstance(x, jax.Array) and jnp.issubdtype(x.dtype, jnp.floating):
        return jnp.asarray(x, dtype=x.dtype) if x.weak_type else x
    return jnp.asarray(x, dtype=jnp.float64)


_Tree = TypeVar("_Tree")


def parameter(**kwargs: Any) -> Any:
    """Declare a free (unconstrained) numeric `equinox.Module` field, converted to a float64 array."""
    kwargs.setdefault("converter", as_float_array)
    return eqx.field(**kwargs)


def positive(**kwargs: Any) -> Any:
    """Declare an `equinox.Module` field that must stay > 0 (converted to a float64 array)."""
    metadata = dict(kwargs.pop("metadata", {}) or {})
    metadata["constraint"] = "positive"
    kwargs.setdefault("converter", as_float_array)
    return eqx.field(metadata=metadata, **kwargs)


def _is_positive(f):
    return f.metadata.get("constraint") == "positive" and not f.metadata.get("static", False)


def _softplus_inv(x):
    x = jnp.maximum(jnp.asarray(x, dtype=jnp.float64), POSITIVE_FLOOR)
    return x + jnp.log(-jnp.expm1(-x))


def _map_fields(model, fn):
    """Apply ``fn`` to every positive field, recursing into sub-modules."""
    if not isinstance(model, eqx.Module):
        return model
    names, values = [], []
    for f in dataclasses.fields(model):
        if f.metadata.get("static", False):
            continue
        val = getattr(model, f.name)
        if isinstance(val, eqx.Module):
            new = _map_fields(val, fn)
        elif isinstance(val, (tuple, list)) and any(isinstance(v, eqx.Module) for v in val):
            new = type(val)(_map_fields(v, fn) for v in val)
        elif _is_positive(f) and val is not None:
            new = fn(val)
        else:
            continue
        names.append(f.name)
        values.append(new)
    if not names:
        return model
    return eqx.tree_at(lambda m: [getattr(m, n) for n in names], model, values, is_leaf=lambda x: x is None)


def unconstrain(model: _Tree) -> _Tree:
    """Physical model -> unconstrained coordinates (positive fields via inverse softplus)."""
    return _map_fields(model, _softplus_inv)


def constrain(raw: _Tree) -> _Tree:
    """Unconstrained coordinates -> physical model (positive fields via softplus)."""
    return _map_fields(raw, jax.nn.softplus)


def log_jacobian(raw: Any) -> jax.Array:
    """log |d constrain / d raw| summed over all positive fields (for densities in raw space)."""
    total = []

    def acc(x):
        total.append(jnp.sum(jax.nn.log_sigmoid(x)))
        return x

    _map_fields(raw, acc)
    return sum(total) if total else jnp.asarray(0.0)


def positive_mask(model: Any) -> Any:
    """PyTree of bools shaped like ``model``: True on leaves that are positivity-constrained."""
    marker = object()
    flagged = _map_fields(model, lambda x: _Flag(marker))
    return jax.tree_util.tree_map(lambda a: isinstance(a, _Flag), flagged, is_leaf=lambda a: isinstance(a, _Flag))


class _Flag:
    """Opaque leaf used to mark positive fields."""

    def __init__(self, tag):
        self.tag = tag
