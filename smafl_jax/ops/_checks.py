"""Shape checks at trace time: precise ValueErrors instead of broadcasting surprises."""

from __future__ import annotations

import jax.numpy as jnp

from .. import _config  # noqa: F401  (x64)


def as_f64(x, name: str, where: str):
    try:
        return jnp.asarray(x, dtype=jnp.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: {name} must be a float array, got {type(x).__name__} ({exc})") from exc


def record(x, name: str, where: str):
    """A 1-D record of at least one sample."""
    x = as_f64(x, name, where)
    if x.ndim != 1:
        raise ValueError(f"{where}: {name} must be 1-D with shape (T,), got shape {x.shape}; use jax.vmap for a batch of records")
    if x.shape[0] == 0:
        raise ValueError(f"{where}: {name} is empty (T = 0); a record needs at least one sample")
    return x


def bank(x, name: str, where: str):
    """A 1-D vector with one entry per operator (at least one)."""
    x = as_f64(x, name, where)
    if x.ndim != 1:
        raise ValueError(f"{where}: {name} must be 1-D with one entry per operator, got shape {x.shape}")
    if x.shape[0] == 0:
        raise ValueError(f"{where}: {name} is empty; the bank needs at least one operator")
    return x


def per_operator(x, name: str, n: int, where: str, default=None):
    """Scalar or ``(n,)``, broadcast to ``(n,)``; ``None`` gives ``default``."""
    if x is None:
        x = default
    x = as_f64(x, name, where)
    if x.ndim == 0:
        return jnp.broadcast_to(x, (n,))
    if x.shape != (n,):
        raise ValueError(f"{where}: {name} must be a scalar or have shape ({n},) (one per operator), got shape {x.shape}")
    return x


def same_length(x, name: str, T: int, where: str):
    """A per-sample ``(T,)`` signal aligned with the input record."""
    x = as_f64(x, name, where)
    if x.shape != (T,):
        raise ValueError(f"{where}: {name} must have shape ({T},) (one value per input sample), got shape {x.shape}")
    return x


def weights(w, n: int, where: str):
    """``None``, ``(n,)`` (one weighted sum) or ``(n, m)`` (m weighted sums)."""
    if w is None:
        return None
    w = as_f64(w, "weights", where)
    if w.ndim not in (1, 2) or w.shape[0] != n:
        raise ValueError(
            f"{where}: weights must have shape ({n},) or ({n}, m) (first axis: one row per operator), got shape {w.shape}"
        )
    return w


def positive_int(v, name: str, where: str):
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise ValueError(f"{where}: {name} must be a positive int, got {v!r}")
    return v


def lift(p, lead: int):
    """``p`` with ``lead`` leading unit axes, to broadcast against ``(*lead_shape, n)`` under strict rank promotion."""
    p = jnp.asarray(p)
    return p.reshape((1,) * lead + p.shape) if p.ndim else p


def form(method, block, segments, T: int, n: int, where: str):
    """Resolve ``method='auto'`` and the default block / segment sizes (static values)."""
    from ._policy import METHODS, choose_method, default_block, default_segments

    if method == "auto":
        method = choose_method(T, n)
    if method not in METHODS:
        raise ValueError(f"{where}: method must be one of 'auto', {', '.join(repr(m) for m in METHODS)}, got {method!r}")
    block = default_block(T, n) if block is None else positive_int(block, "block", where)
    segments = default_segments(T, n) if segments is None else positive_int(segments, "segments", where)
    # sizes that do not apply to the form are not part of the compiled function's identity
    return method, (block if method == "chunked" else None), (segments if method == "segmented" else None)


def readout(w):
    """Output of one step: the states themselves, or their weighted sum(s)."""
    if w is None:
        return lambda y: y
    return lambda y: y @ w
