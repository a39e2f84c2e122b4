"""Bank of relays (Preisach hysterons), crisp or ramp, as clamp recurrences.

Relay ``m`` with switch-up threshold ``a_m`` and switch-down threshold ``b_m``
(``a_m >= b_m``), state ``R_m(k)`` in ``[0, 1]``:

* crisp (``width=None``): ``R = 1`` once ``u >= a``, ``R = 0`` once ``u <= b``,
  otherwise kept; up wins on a tie, so ``a == b`` is a reversible step ``u >= a``;
* ramp (``width = w > 0``): thresholds spread uniformly over ``w``,
  ``R <- max( min(R, S((u - b) / w)), S((u - a) / w) )`` with
  ``S(x) = clip(x + 1/2, 0, 1)`` (continuous in ``u``; equals the crisp relay
  whenever ``u`` sits on a cell edge of a grid of spacing ``w``).  ``w = 0``
  inside the ramp form falls back to the crisp rule (no 0/0).

Both are the clamp ``R -> max(lo, min(hi, R))`` with ``lo`` the fraction forced
up and ``hi`` the fraction allowed up, so the four forms agree bit for bit.
Initial state ``y0`` (default 0: every relay down, the virgin state).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .. import _config  # noqa: F401  (x64)
from . import _checks as ck
from ._engine import CLAMP, run

__all__ = ["relay_bounds", "relay_step", "relay_scan", "relay_assoc", "relay_chunked", "relay_segmented", "relay"]


def relay_bounds(u, a, b, width=None):
    """``(lo, hi)``: fraction of each relay forced up and allowed up at input ``u`` (any leading shape)."""
    u = jnp.asarray(u)
    lead = u.ndim
    u = u[..., None]
    a, b = ck.lift(a, lead), ck.lift(b, lead)
    if width is None:
        return (u >= a).astype(u.dtype), (u > b).astype(u.dtype)
    positive = width > 0
    safe = jnp.where(positive, width, 1.0)  # the untaken branch must not divide by 0 (its gradient would be NaN)

    def ramp(t):
        return jnp.clip((u - t) / safe + 0.5, 0.0, 1.0)

    lo = jnp.where(positive, ramp(a), (u >= a).astype(u.dtype))
    hi = jnp.where(positive, ramp(b), (u > b).astype(u.dtype))
    return lo, hi


def relay_step(y, u, a, b, width=None):
    """One step for `jax.lax.scan`: ``(R(k-1), u(k)) -> (R(k), R(k))``."""
    lo, hi = relay_bounds(u, a, b, width)
    y = jnp.maximum(lo, jnp.minimum(hi, y))
    return y, y


def _impl(u, a, b, y0, weights, width, *, method, block, segments):
    def elements(x):
        return relay_bounds(x, a, b, width)

    return run(method, CLAMP, elements, u, y0, ck.readout(weights), block=block, segments=segments)


_traced = eqx.debug.assert_max_traces(_impl, max_traces=None)
_jit = eqx.filter_jit(_traced)


def _jitted(u, a, b, y0, weights, width, *, where, method, block, segments):
    u = ck.record(u, "u", where)
    a = ck.bank(a, "switch-up thresholds a", where)
    n = a.shape[0]
    b = ck.per_operator(b, "switch-down thresholds b", n, where)
    y0 = ck.per_operator(y0, "y0", n, where, default=0.0)
    weights = ck.weights(weights, n, where)
    if width is not None:
        width = ck.as_f64(width, "width", where)
        if width.ndim != 0:
            raise ValueError(f"{where}: width must be a scalar (one ramp width for every relay), got shape {width.shape}")
    method, block, segments = ck.form(method, block, segments, u.shape[0], n, where)
    return _jit(u, a, b, y0, weights, width, method=method, block=block, segments=segments)


_DOC_ARGS = """
    u: ``(T,)`` input.  a, b: ``(n,)`` switch-up / switch-down thresholds (``b`` may be a scalar).
    y0: scalar or ``(n,)`` initial states in [0, 1] (default 0).  width: ``None`` (crisp relays) or a
    scalar ramp width.  weights: ``None`` -> ``(T, n)`` states; ``(n,)`` -> ``(T,)``; ``(n, m)`` -> ``(T, m)``.
"""


def relay_scan(u, a, b, y0=None, *, width=None, weights=None) -> jax.Array:
    return _jitted(u, a, b, y0, weights, width, method="scan", block=None, segments=None, where="relay_scan")


def relay_assoc(u, a, b, y0=None, *, width=None, weights=None) -> jax.Array:
    return _jitted(u, a, b, y0, weights, width, method="assoc", block=None, segments=None, where="relay_assoc")


def relay_chunked(u, a, b, y0=None, *, width=None, weights=None, block: int | None = None) -> jax.Array:
    return _jitted(u, a, b, y0, weights, width, method="chunked", block=block, segments=None, where="relay_chunked")


def relay_segmented(u, a, b, y0=None, *, width=None, weights=None, segments: int | None = None) -> jax.Array:
    return _jitted(u, a, b, y0, weights, width, method="segmented", block=None, segments=segments, where="relay_segmented")


def relay(
    u, a, b, y0=None, *, width=None, weights=None, method: str = "auto", block: int | None = None, segments: int | None = None
) -> jax.Array:
    return _jitted(u, a, b, y0, weights, width, method=method, block=block, segments=segments, where="relay")


relay_scan.__doc__ = "Relay bank, sequential `lax.scan`.\n" + _DOC_ARGS
relay_assoc.__doc__ = "Relay bank by `lax.associative_scan` over the whole record.\n" + _DOC_ARGS
relay_chunked.__doc__ = "Relay bank: `lax.scan` over blocks, each by `lax.associative_scan`.\n" + _DOC_ARGS
relay_segmented.__doc__ = "Relay bank on ``segments`` pieces in lockstep (two passes).\n" + _DOC_ARGS
relay.__doc__ = "Relay bank; ``method``: 'auto', 'scan', 'assoc', 'chunked' or 'segmented'.\n" + _DOC_ARGS
