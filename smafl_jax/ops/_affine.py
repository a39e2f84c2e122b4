"""First-order affine (linear time-varying) recurrence ``x(k) = a(k) x(k-1) + b(k)``.

Covers the thermal lag (constant ``a = exp(-k1 dt)``, ``b = (1 - a) g U^2``),
sensor lag and creep (`lowpass`), and thermal laws with a time-varying rate
(``a(k) = exp(-k1(k) dt)``).  Column-batched: ``b`` of shape ``(T, n)`` filters
the ``n`` columns of a feature matrix at once.

Shapes: ``b`` is ``(T,)`` or ``(T, n)``.  ``a`` is a scalar (constant), ``(T,)``
or ``(T, 1)`` (one coefficient per step, shared by all columns), ``(1, n)`` (one
constant per column) or ``b``'s shape.  ``x0`` (state before the
first sample) is a scalar or the state shape (``()`` or ``(n,)``); default 0.

Affine maps compose associatively, ``(a2, b2) o (a1, b1) = (a2 a1, a2 b1 + b2)``;
the forms agree to rounding (~1e-15 relative; see `_engine`).  All forms are
differentiable in ``a``, ``b`` and ``x0``.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .. import _config  # noqa: F401  (x64)
from . import _checks as ck
from ._engine import AFFINE, run

__all__ = ["affine_step", "affine_scan", "affine_assoc", "affine_chunked", "affine_segmented", "affine", "lowpass"]


def affine_step(x, ab):
    """One step for `jax.lax.scan`: ``(x(k-1), (a(k), b(k))) -> (x(k), x(k))``."""
    a, b = ab
    x = a * x + b
    return x, x


def _normalise_a(a, b, where, bname="b"):
    """``(a, time_varying)`` with ``a`` broadcastable against one step (constant) or all steps of ``b``."""
    T = b.shape[0]
    state = b.shape[1:]
    if a.ndim == 0:
        return a, False
    if b.ndim == 1:
        if a.shape == (T,):
            return a, True
    else:
        n = state[0]
        if a.shape == (1, n):
            return a.reshape(n), False
        if a.shape in ((T,), (T, 1)):
            return a.reshape(T, 1), True
        if a.shape == b.shape:
            return a, True
    allowed = f"a scalar or ({T},)" if b.ndim == 1 else f"a scalar, ({T},), ({T}, 1), (1, {state[0]}) or {b.shape}"
    raise ValueError(f"{where}: a must be {allowed} to match {bname} of shape {b.shape}, got shape {a.shape}")


def _impl(a, b, x0, *, varying, method, block, segments):
    if varying:
        xs = (a, b)

        def elements(x):
            return x
    else:
        xs = b

        def elements(x):
            return a, x

    return run(method, AFFINE, elements, xs, x0, lambda x: x, block=block, segments=segments)


_traced = eqx.debug.assert_max_traces(_impl, max_traces=None)
_jit = eqx.filter_jit(_traced)


def _jitted(a, b, x0, *, where, method, block, segments):
    b = ck.as_f64(b, "b", where)
    if b.ndim not in (1, 2):
        raise ValueError(f"{where}: b must have shape (T,) or (T, n) (time on the first axis), got shape {b.shape}")
    if b.shape[0] == 0:
        raise ValueError(f"{where}: b is empty (T = 0); a record needs at least one sample")
    T, state = b.shape[0], b.shape[1:]
    a, varying = _normalise_a(ck.as_f64(a, "a", where), b, where)
    x0 = ck.as_f64(0.0 if x0 is None else x0, "x0", where)
    if x0.ndim != 0 and x0.shape != state:
        raise ValueError(f"{where}: x0 must be a scalar or have shape {state} (the state of one step), got shape {x0.shape}")
    x0 = jnp.broadcast_to(x0, state)
    method, block, segments = ck.form(method, block, segments, T, state[0] if state else 1, where)
    return _jit(a, b, x0, varying=varying, method=method, block=block, segments=segments)


_DOC_ARGS = """
    a: scalar, ``(T,)``, ``(T, 1)``, ``(1, n)`` or ``b``'s shape.  b: ``(T,)`` or ``(T, n)``.
    x0: scalar or state shape (default 0).  Returns the states ``x(k)``, shape of ``b``.
"""


def affine_scan(a, b, x0=None) -> jax.Array:
    return _jitted(a, b, x0, method="scan", block=None, segments=None, where="affine_scan")


def affine_assoc(a, b, x0=None) -> jax.Array:
    return _jitted(a, b, x0, method="assoc", block=None, segments=None, where="affine_assoc")


def affine_chunked(a, b, x0=None, *, block: int | None = None) -> jax.Array:
    return _jitted(a, b, x0, method="chunked", block=block, segments=None, where="affine_chunked")


def affine_segmented(a, b, x0=None, *, segments: int | None = None) -> jax.Array:
    return _jitted(a, b, x0, method="segmented", block=None, segments=segments, where="affine_segmented")


def affine(a, b, x0=None, *, method: str = "auto", block: int | None = None, segments: int | None = None) -> jax.Array:
    return _jitted(a, b, x0, method=method, block=block, segments=segments, where="affine")


def lowpass(x, a, z0=None, *, method: str = "auto", block: int | None = None, segments: int | None = None) -> jax.Array:
    """First-order lag ``z(k) = a z(k-1) + (1 - a) x(k)`` (exact ZOH lag with ``a = exp(-dt / tau)``).

    ``x``: ``(T,)`` or ``(T, n)`` (columns filtered independently); ``a`` as in `affine`;
    ``z0``: state before the first sample (default 0; pass ``x[0]`` to start at rest).
    """
    x = ck.as_f64(x, "x", "lowpass")
    if x.ndim not in (1, 2) or x.shape[0] == 0:
        raise ValueError(f"lowpass: x must have shape (T,) or (T, n) with T >= 1, got shape {x.shape}")
    a_n, varying = _normalise_a(ck.as_f64(a, "a", "lowpass"), x, "lowpass", "x")
    if not varying and a_n.ndim == 1:
        a_n = a_n[None, :]  # one constant per column
    return _jitted(a_n, (1.0 - a_n) * x, z0, method=method, block=block, segments=segments, where="lowpass")


affine_scan.__doc__ = "Affine recurrence, sequential `lax.scan`.\n" + _DOC_ARGS
affine_assoc.__doc__ = "Affine recurrence by `lax.associative_scan` over the whole record.\n" + _DOC_ARGS
affine_chunked.__doc__ = "Affine recurrence: `lax.scan` over blocks, each by `lax.associative_scan`.\n" + _DOC_ARGS
affine_segmented.__doc__ = "Affine recurrence on ``segments`` pieces in lockstep (two passes).\n" + _DOC_ARGS
affine.__doc__ = "Affine recurrence; ``method``: 'auto', 'scan', 'assoc', 'chunked' or 'segmented'.\n" + _DOC_ARGS
