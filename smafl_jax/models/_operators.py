"""Play operators (eq. 1 of Xiang et al. 2017) for the models, and the models' ``method="auto"`` rule.

Convention used throughout the toolkit.  For a bank of ``n`` operators with
thresholds ``r`` (>= 0) and tilts ``alpha`` (> 0) driven by one input signal
``u(k)``, the state of operator ``i`` after sample ``k`` is

    F_i(k) = max( u(k) - r_i , min( alpha_i * (u(k) + r_i), F_i(k-1) ) )

``alpha_i = 1`` is the classical symmetric play (backlash) operator.  The
state *before* the first sample, ``F_i(-1)``, is the explicit initial state
``y0`` (default 0: the actuator starts relaxed).  `consistent_initial_state`
gives the alternative choice "the operator sits at the value the first input
implies when approached from rest".

Each step is a clamp ``y -> max(lo, min(hi, y))``; clamps compose
associatively with max/min only, so every evaluation form of `smafl_jax.ops`
(``scan``, ``assoc``, ``chunked``, ``segmented``) gives the same numbers bit
for bit.  This module is the models' thin front end to those kernels: it keeps
the toolkit's historical signatures (scalar ``r`` allowed, ``play_weighted``)
and resolves ``method="auto"`` with `choose_model_method`, the rule measured
on whole-model forward passes (benchmarks/bench_parallel_time.py).
"""

from __future__ import annotations

from typing import TypeVar

import jax
import jax.numpy as jnp
from jax.typing import ArrayLike

from .. import _config, ops  # noqa: F401  (_config: x64)

__all__ = [
    "MODEL_METHODS",
    "choose_model_method",
    "resolve_method",
    "model_with_method",
    "play_step",
    "play",
    "play_scan",
    "play_assoc",
    "play_weighted",
    "consistent_initial_state",
]

MODEL_METHODS = ("auto", *ops.METHODS)

_ACCELERATORS = ("gpu", "cuda", "rocm", "tpu")


def choose_model_method(T: int, n: int, backend: str | None = None) -> str:
    """Evaluation form for a model of ``T`` samples and ``n`` operators (or state entries) on ``backend``.

    CPU: ``scan``.  Measured (benchmarks/bench_parallel_time.py, 2 shared cores, truth cascade of
    24 operators): ``assoc`` and ``chunked`` run 4-25x slower than scan and compile in 8-22 s
    (scan: ~1 s); ``segmented`` runs the forward pass 1.2-2.2x faster than scan for T = 1e4..1e7
    (and 2x at 50 operators), but its loss-and-gradient (what fit and sample evaluate) is 0.8-0.9x
    scan at T = 1e5..1e6 and compiles 2-3x longer, so it is not the default; ask for it
    explicitly for repeated forward passes of long records.
    Accelerators (NOT measured in this repository; from the H100 figures of issue 15: ~12 us per
    scan step, ``assoc`` 8.8 ms at T = 1e6, ``assoc`` compile 3 min at T = 1e7): ``scan`` for tiny
    records, ``assoc`` up to 2^20 samples, ``chunked`` (compile time independent of T) beyond.
    """
    b = jax.default_backend() if backend is None else str(backend).lower()
    if b in _ACCELERATORS:
        if T <= 64:
            return "scan"
        return "assoc" if T <= 2**20 else "chunked"
    return "scan"


def resolve_method(method: str, T: int, n: int, where: str = "method") -> str:
    """``method`` itself, or the `choose_model_method` choice for ``"auto"``; ValueError names the options."""
    if method == "auto":
        return choose_model_method(T, n)
    if method not in ops.METHODS:
        raise ValueError(f"{where} must be one of {MODEL_METHODS}, got {method!r}")
    return method


def _has_methods(x) -> bool:
    """A part whose class declares ``evaluation_methods`` (EUPI, JouleThermal): its ``method`` field picks the form."""
    return bool(getattr(type(x), "evaluation_methods", ()))


_Tree = TypeVar("_Tree")


def model_with_method(model: _Tree, method: str) -> _Tree:
    """Copy of ``model`` with every part that has evaluation methods (EUPI, JouleThermal) evaluated by ``method``.

    Works for a `Cascade`, an `EUPI`, a `JouleThermal` or any model containing them (e.g. an
    `ExtendedModel`; its effects' own recurrences keep their sequential form).  ValueError when
    ``method`` is unknown or the model has no part with an evaluation method.
    """
    import dataclasses

    if method not in MODEL_METHODS:
        raise ValueError(f"method must be one of {MODEL_METHODS}, got {method!r}")
    found = []

    def switch(x):
        if _has_methods(x):
            found.append(type(x).__name__)
            return dataclasses.replace(x, method=method)
        return x

    out = jax.tree.map(switch, model, is_leaf=_has_methods)
    if not found:
        raise ValueError(f"{type(model).__name__} has no EUPI or JouleThermal part, so no evaluation method to set")
    return out


def _bounds(u, r, alpha):
    return u - r, alpha * (u + r)


def play_step(carry: ArrayLike, u: ArrayLike, r: ArrayLike, alpha: ArrayLike) -> tuple[jax.Array, jax.Array]:
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


def play(u: ArrayLike, r: ArrayLike, alpha: ArrayLike = 1.0, y0: ArrayLike | None = None, method: str = "scan") -> jax.Array:
    """Outputs ``(T, n)`` of a bank of play operators.

    ``method``: ``"scan"`` (sequential), ``"assoc"`` / ``"chunked"`` / ``"segmented"``
    (exact parallel-in-time forms, `smafl_jax.ops`) or ``"auto"`` (`choose_model_method`).
    """
    u, r, alpha, y0 = _prepare(u, r, alpha, y0)
    method = resolve_method(method, u.shape[0], r.shape[0])
    if r.shape[0] == 0:  # a model without operators (e.g. EUPI with n_sym = n_asym = 0); the kernels need n >= 1
        return jnp.zeros((u.shape[0], 0))
    return ops.play(u, r, alpha, y0, method=method)


def play_scan(u: ArrayLike, r: ArrayLike, alpha: ArrayLike = 1.0, y0: ArrayLike | None = None) -> jax.Array:
    """Outputs ``(T, n)`` of ``n`` play operators via `jax.lax.scan`."""
    return play(u, r, alpha, y0, method="scan")


def play_assoc(u: ArrayLike, r: ArrayLike, alpha: ArrayLike = 1.0, y0: ArrayLike | None = None) -> jax.Array:
    """Same as `play_scan`, evaluated in parallel with `jax.lax.associative_scan`."""
    return play(u, r, alpha, y0, method="assoc")


def play_weighted(
    u: ArrayLike, r: ArrayLike, alpha: ArrayLike, weights: ArrayLike, y0: ArrayLike | None = None, method: str = "scan"
) -> jax.Array:
    """``play(u, r, alpha, y0) @ weights`` without storing the ``(T, n)`` outputs for ``method="scan"``.

    With ``"scan"`` the weighted sum is taken inside the scan step, so only ``T``
    numbers are written instead of ``T * n``: the forward pass of a Prandtl-Ishlinskii
    model is then compute-bound rather than memory-bound (2-4x faster on CPU for
    50-200 operators, see benchmarks/).  The parallel forms (``"assoc"``,
    ``"chunked"``, ``"segmented"``, or ``"auto"``) apply the same weights to their states.
    Use `play_scan` when the individual operator outputs are needed (e.g. the design matrix).
    """
    u, r, alpha, y0 = _prepare(u, r, alpha, y0)
    weights = jnp.asarray(weights, dtype=jnp.float64)
    if weights.shape != r.shape:
        raise ValueError(f"weights must have one entry per operator, shape {r.shape}, got {weights.shape}")
    method = resolve_method(method, u.shape[0], r.shape[0])
    if r.shape[0] == 0:
        return jnp.zeros_like(u)
    return ops.play(u, r, alpha, y0, weights=weights, method=method)


def consistent_initial_state(u0: ArrayLike, r: ArrayLike, alpha: ArrayLike = 1.0) -> jax.Array:
    """Initial state the operators reach when ``u0`` is approached from a relaxed (zero) state."""
    lo, hi = _bounds(jnp.asarray(u0, dtype=jnp.float64), jnp.asarray(r), jnp.asarray(alpha))
    return jnp.maximum(lo, jnp.minimum(hi, jnp.zeros_like(lo)))
