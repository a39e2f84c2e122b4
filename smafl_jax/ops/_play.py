"""Bank of unparallel play operators, eq. (1) of Xiang et al. (2017).

For thresholds ``r_i >= 0``, tilts ``alpha_i > 0`` and input ``u(k)``:

    F_i(k) = max( u(k) - r_i c(k), min( alpha_i (u(k) + r_i c(k)), F_i(k-1) ) ),   F_i(-1) = y0_i

``c(k) = 1`` is the paper's operator; a per-sample threshold scale ``c(k) > 0``
(``scale=``) gives rate-dependent thresholds ``r_i c(k)``.  ``alpha_i = 1`` is
the classical (symmetric) play operator.  The initial state ``y0`` is explicit
(default 0: the actuator starts relaxed).

Each step is the clamp ``F -> max(lo(k), min(hi(k), F))``; clamps compose
associatively with max/min only, so `play_scan`, `play_assoc`,
`play_chunked` and `play_segmented` return the same floating-point numbers
bit for bit.  ``weights=`` (shape ``(n,)`` or ``(n, m)``) returns
``F @ weights`` (a Prandtl-Ishlinskii forward pass) without storing the
``(T, n)`` states.  `play` picks the form with `choose_method`.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .. import _config  # noqa: F401  (x64)
from . import _checks as ck
from ._engine import CLAMP, run

__all__ = [
    "play_step",
    "play_bounds",
    "play_scan",
    "play_assoc",
    "play_chunked",
    "play_segmented",
    "play",
    "play_consistent_state",
]


def play_bounds(u, r, alpha, scale=None):
    """Clamp bounds ``(lo, hi)`` of each operator at input ``u`` (any leading shape; ``(..., n)``)."""
    u = jnp.asarray(u)
    lead = u.ndim
    u = u[..., None]
    r, alpha = ck.lift(r, lead), ck.lift(alpha, lead)
    rk = r if scale is None else r * jnp.asarray(scale)[..., None]
    return u - rk, alpha * (u + rk)


def play_step(y, u, r, alpha=1.0, scale=None):
    """One step of the bank for `jax.lax.scan`: ``(F(k-1), u(k)) -> (F(k), F(k))``.

    ``y``, ``r``, ``alpha``: ``(n,)``; ``u`` and ``scale`` (optional ``c(k)``): scalars.
    """
    lo, hi = play_bounds(u, r, alpha, scale)
    y = jnp.maximum(lo, jnp.minimum(hi, y))
    return y, y


def play_consistent_state(u0, r, alpha=1.0):
    """State each operator reaches when ``u0`` is applied from the relaxed state 0."""
    lo, hi = play_bounds(u0, jnp.asarray(r, dtype=jnp.float64), jnp.asarray(alpha, dtype=jnp.float64))
    return jnp.maximum(lo, jnp.minimum(hi, 0.0))


def _impl(u, r, alpha, y0, weights, scale, *, method, block, segments):
    xs = u if scale is None else (u, scale)

    def elements(x):
        return play_bounds(x, r, alpha) if scale is None else play_bounds(x[0], r, alpha, x[1])

    return run(method, CLAMP, elements, xs, y0, ck.readout(weights), block=block, segments=segments)


# One trace per (shapes, method, block, segments); the counter lets tests check that new values never retrace.
_traced = eqx.debug.assert_max_traces(_impl, max_traces=None)
_jit = eqx.filter_jit(_traced)


def _jitted(u, r, alpha, y0, weights, scale, *, where, method, block, segments):
    """Check shapes (trace time, precise messages), make every value an array, pick the form, run it jitted."""
    u = ck.record(u, "u", where)
    r = ck.bank(r, "thresholds r", where)
    n = r.shape[0]
    alpha = ck.per_operator(alpha, "alpha", n, where)
    y0 = ck.per_operator(y0, "y0", n, where, default=0.0)
    weights = ck.weights(weights, n, where)
    if scale is not None:
        scale = ck.same_length(scale, "scale", u.shape[0], where)
    method, block, segments = ck.form(method, block, segments, u.shape[0], n, where)
    return _jit(u, r, alpha, y0, weights, scale, method=method, block=block, segments=segments)


_DOC_ARGS = """
    u: ``(T,)`` input record.  r: ``(n,)`` thresholds.  alpha: scalar or ``(n,)`` tilts.
    y0: scalar or ``(n,)`` initial states (default 0).  weights: ``None`` -> ``(T, n)``
    states; ``(n,)`` -> ``(T,)`` weighted sum; ``(n, m)`` -> ``(T, m)``.
    scale: optional ``(T,)`` per-sample threshold scale ``c(k)``.
    Differentiable in every array argument; `jax.vmap` over records works.
"""


def play_scan(u, r, alpha=1.0, y0=None, *, weights=None, scale=None) -> jax.Array:
    return _jitted(u, r, alpha, y0, weights, scale, method="scan", block=None, segments=None, where="play_scan")


def play_assoc(u, r, alpha=1.0, y0=None, *, weights=None, scale=None) -> jax.Array:
    return _jitted(u, r, alpha, y0, weights, scale, method="assoc", block=None, segments=None, where="play_assoc")


def play_chunked(u, r, alpha=1.0, y0=None, *, weights=None, scale=None, block: int | None = None) -> jax.Array:
    return _jitted(u, r, alpha, y0, weights, scale, method="chunked", block=block, segments=None, where="play_chunked")


def play_segmented(u, r, alpha=1.0, y0=None, *, weights=None, scale=None, segments: int | None = None) -> jax.Array:
    return _jitted(u, r, alpha, y0, weights, scale, method="segmented", block=None, segments=segments, where="play_segmented")


def play(
    u,
    r,
    alpha=1.0,
    y0=None,
    *,
    weights=None,
    scale=None,
    method: str = "auto",
    block: int | None = None,
    segments: int | None = None,
) -> jax.Array:
    return _jitted(u, r, alpha, y0, weights, scale, method=method, block=block, segments=segments, where="play")


play_scan.__doc__ = "Play-operator bank, sequential `lax.scan` (one step per sample).\n" + _DOC_ARGS
play_assoc.__doc__ = "Play-operator bank by `lax.associative_scan` over the whole record (GPU, T up to ~1e6).\n" + _DOC_ARGS
play_chunked.__doc__ = (
    "Play-operator bank: `lax.scan` over blocks of ``block`` samples, each by `lax.associative_scan`\n"
    "(compile time and scratch memory independent of T; GPU for long records).\n" + _DOC_ARGS
)
play_segmented.__doc__ = (
    "Play-operator bank on ``segments`` pieces of the record in lockstep (two passes; fastest exact CPU form\n"
    "for banks of tens of operators and more).\n" + _DOC_ARGS
)
play.__doc__ = (
    "Play-operator bank; ``method`` is 'auto' (`choose_method`), 'scan', 'assoc', 'chunked' or 'segmented'.\n" + _DOC_ARGS
)
