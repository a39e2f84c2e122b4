"""Play operators (eq. 1 of Xiang et al. 2017) as scan recurrences.

Convention used throughout the toolkit.  For a bank of ``n`` operators with
thresholds ``r`` (>= 0) and tilts ``alpha`` (> 0) driven by one input signal
``u(k)``, the state of operator ``i`` after sample ``k`` is

    F_i(k) = max( u(k) - r_i , min( alpha_i * (u(k) + r_i), F_i(k-1) ) )

``alpha_i = 1`` is the classical symmetric play (backlash) operator.  The
state *before* the first sample, ``F_i(-1)``, is the explicit initial state
``y0`` (default 0: the actuator starts relaxed).  `consistent_initial_state`
gives the alternative choice "the operator sits at the value the first input
implies when approached from rest".

Each step is a clamp ``y -> max(lo, min(hi, y))``.  Clamps are closed under
composition, ``(lo2, hi2) o (lo1, hi1) = (max(lo2, min(lo1, hi2)), min(hi1, hi2))``,
which is associative, so the whole record can also be evaluated with
`jax.lax.associative_scan` in O(log T) depth (useful on GPUs and long records).
Both paths use only max/min, so they agree bit for bit.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from . import _config  # noqa: F401  (x64)

__all__ = ["play_step", "play", "play_scan", "play_assoc", "play_weighted", "consistent_initial_state"]


def _bounds(u, r, alpha):
    return u - r, alpha * (u + r)


def play_step(carry, u, r, alpha):
    """One step of a bank of play operators: ``(F(k-1), u(k)) -> (F(k), F(k))``."""
    lo, hi = _bounds(u, r, alpha)
    y = jnp.maximum(lo, jnp.minimum(hi, carry))
    return y, y


def _prepare(u, r, alpha, y0):
    u = jnp.asarray(u, dtype=jnp.float64)
    r = jnp.atleast_1d(jnp.asarray(r, dtype=jnp.float64))
    alpha = jnp.broadcast_to(jnp.asarray(alpha, dtype=jnp.float64), r.shape)
    if u.ndim != 1:
        raise ValueError(f"play operators take a 1-D input signal, got shape {u.shape}; use jax.vmap for batches")
    if r.ndim != 1:
        raise ValueError(f"thresholds r must be 1-D (one per operator), got shape {r.shape}")
    y0 = jnp.zeros_like(r) if y0 is None else jnp.broadcast_to(jnp.asarray(y0, dtype=jnp.float64), r.shape)
    return u, r, alpha, y0


def play_scan(u, r, alpha=1.0, y0=None):
    """Outputs ``(T, n)`` of ``n`` play operators via `jax.lax.scan`."""
    u, r, alpha, y0 = _prepare(u, r, alpha, y0)

    def step(carry, uk):
        return play_step(carry, uk, r, alpha)

    _, ys = jax.lax.scan(step, y0, u)
    return ys


def play_weighted(u, r, alpha, weights, y0=None):
    """``play_scan(u, r, alpha, y0) @ weights`` without storing the ``(T, n)`` outputs.

    The weighted sum is taken inside the scan step, so only ``T`` numbers are
    written instead of ``T * n``: the forward pass of a Prandtl-Ishlinskii
    model is then compute-bound rather than memory-bound (2-4x faster on CPU
    for 50-200 operators, see benchmarks/).  Use `play_scan` when the
    individual operator outputs are needed (e.g. the design matrix).
    """
    u, r, alpha, y0 = _prepare(u, r, alpha, y0)
    weights = jnp.asarray(weights, dtype=jnp.float64)
    if weights.shape != r.shape:
        raise ValueError(f"weights must have one entry per operator, shape {r.shape}, got {weights.shape}")

    def step(carry, uk):
        y, _ = play_step(carry, uk, r, alpha)
        return y, y @ weights

    _, out = jax.lax.scan(step, y0, u)
    return out


def _compose(first, second):
    # `first` acts earlier in time; result is second o first.
    lo1, hi1 = first
    lo2, hi2 = second
    return jnp.maximum(lo2, jnp.minimum(lo1, hi2)), jnp.minimum(hi1, hi2)


def play_assoc(u, r, alpha=1.0, y0=None):
    """Same as `play_scan`, evaluated in parallel with `jax.lax.associative_scan`."""
    u, r, alpha, y0 = _prepare(u, r, alpha, y0)
    lo, hi = _bounds(u[:, None], r[None, :], alpha[None, :])
    los, his = jax.lax.associative_scan(_compose, (lo, hi), axis=0)
    return jnp.maximum(los, jnp.minimum(his, y0[None, :]))


def play(u, r, alpha=1.0, y0=None, method="scan"):
    """Bank of play operators; ``method`` is ``"scan"`` (sequential) or ``"assoc"`` (parallel)."""
    if method == "scan":
        return play_scan(u, r, alpha, y0)
    if method == "assoc":
        return play_assoc(u, r, alpha, y0)
    raise ValueError(f"method must be 'scan' or 'assoc', got {method!r}")


def consistent_initial_state(u0, r, alpha=1.0):
    """Initial state the operators reach when ``u0`` is approached from a relaxed (zero) state."""
    lo, hi = _bounds(jnp.asarray(u0, dtype=jnp.float64), jnp.asarray(r), jnp.asarray(alpha))
    return jnp.maximum(lo, jnp.minimum(hi, jnp.zeros_like(lo)))
