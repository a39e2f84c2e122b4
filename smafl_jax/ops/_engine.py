"""Evaluation drivers shared by every kernel: one recurrence, four evaluation orders.

A kernel is described by a *monoid* of per-step maps (`Monoid`) and a function
``elements(x)`` giving the map of each time step from the driving input ``x``.
With ``e(k) = elements(x(k))`` the state obeys ``y(k) = apply(e(k), y(k-1))``,
and ``combine(earlier, later)`` composes two maps (associative, with an
identity).  Two monoids cover the package:

* clamps ``y -> max(lo, min(hi, y))`` (play operators, crisp and ramp relays):
  composition uses only max/min, so every evaluation order gives the same
  floating-point numbers bit for bit;
* affine maps ``x -> a x + b`` (lags, creep, thermal laws): composition
  re-associates products and sums, so orders agree to rounding (~1e-15
  relative, growing like log T for the tree order of ``assoc``).

Drivers (all exact; they differ in cost, memory and compile time):

``scan``       one `lax.scan` over the record (T sequential steps).
``assoc``      `lax.associative_scan` over the whole record: O(log T) depth,
               O(T n) memory for the prefix maps, compile time grows with T.
``chunked``    `lax.scan` over blocks of ``block`` steps, each block by
               `lax.associative_scan`; the carried state composes exactly.
               Compile time and scratch memory depend on ``block``, not on T.
``segmented``  the record is cut into ``segments`` contiguous pieces run in
               lockstep (the state gets a segment axis): pass 1 composes each
               piece's map, a short scan over pieces gives every piece's exact
               initial state, pass 2 re-runs the pieces from those states and
               writes the outputs.  2x the step work, but T / segments loop
               iterations on a ``segments``-times wider vector: the fastest
               exact form on CPU for banks of >= ~50 operators (benchmarks/).

``readout(y)`` maps a state ``(..., n)`` to the output of one step (identity
for the bank outputs, ``y @ w`` for a weighted sum that never stores ``T x n``).
Padding a record to whole blocks/segments appends copies of the last input
sample; later samples cannot change earlier outputs, and the padded outputs
are dropped, so padding never affects the result.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from .. import _config  # noqa: F401  (x64)


class Monoid(NamedTuple):
    """Composition law of a family of per-step maps."""

    combine: Callable[[Any, Any], Any]  # (earlier, later) -> later o earlier
    apply: Callable[[Any, Any], Any]  # (map, state) -> new state
    identity: Callable[[tuple[int, ...]], Any]  # state shape -> identity map of that shape


def _clamp_combine(first, second):
    lo1, hi1 = first
    lo2, hi2 = second
    return jnp.maximum(lo2, jnp.minimum(lo1, hi2)), jnp.minimum(hi1, hi2)


def _clamp_apply(e, y):
    lo, hi = e
    return jnp.maximum(lo, jnp.minimum(hi, y))


def _clamp_identity(shape):
    return jnp.full(shape, -jnp.inf), jnp.full(shape, jnp.inf)


def _affine_combine(first, second):
    a1, b1 = first
    a2, b2 = second
    return a2 * a1, a2 * b1 + b2


def _affine_apply(e, x):
    a, b = e
    return a * x + b


def _affine_identity(shape):
    return jnp.ones(shape), jnp.zeros(shape)


CLAMP = Monoid(_clamp_combine, _clamp_apply, _clamp_identity)
AFFINE = Monoid(_affine_combine, _affine_apply, _affine_identity)


def _leading(xs) -> int:
    return jax.tree_util.tree_leaves(xs)[0].shape[0]


def _pad_to(xs, total: int):
    """Append copies of the last sample so the leading axis has length ``total``."""
    T = _leading(xs)
    if total == T:
        return xs
    return jax.tree_util.tree_map(lambda x: jnp.concatenate([x, jnp.repeat(x[-1:], total - T, axis=0)], axis=0), xs)


def _broadcast_elements(e, shape):
    return jax.tree_util.tree_map(lambda v: jnp.broadcast_to(v, shape), e)


def run_scan(monoid: Monoid, elements, xs, y0, readout):
    """Sequential form: one `lax.scan` step per sample."""

    def step(y, x):
        y = monoid.apply(elements(x), y)
        return y, readout(y)

    return jax.lax.scan(step, y0, xs)[1]


def run_assoc(monoid: Monoid, elements, xs, y0, readout):
    """Parallel form: prefix compositions of all T maps by `lax.associative_scan`."""
    T = _leading(xs)
    e = _broadcast_elements(elements(xs), (T, *y0.shape))
    prefix = jax.lax.associative_scan(monoid.combine, e, axis=0)
    return readout(monoid.apply(prefix, y0[None]))


def run_chunked(monoid: Monoid, elements, xs, y0, readout, block: int):
    """`lax.scan` over blocks of ``block`` samples, each block evaluated by `run_assoc`."""
    T = _leading(xs)
    n_blocks = -(-T // block)
    xb = jax.tree_util.tree_map(lambda x: x.reshape(n_blocks, block, *x.shape[1:]), _pad_to(xs, n_blocks * block))

    def step(y, x):
        e = _broadcast_elements(elements(x), (block, *y.shape))
        states = monoid.apply(jax.lax.associative_scan(monoid.combine, e, axis=0), y[None])
        return states[-1], readout(states)

    out = jax.lax.scan(step, y0, xb)[1]
    return out.reshape(n_blocks * block, *out.shape[2:])[:T]


def run_segmented(monoid: Monoid, elements, xs, y0, readout, segments: int, segment_axis_last: bool = True):
    """Two passes over ``segments`` contiguous pieces of the record run in lockstep (see module doc).

    The state carries the segment axis last, ``(*state, S)``, by default: the per-step
    input row then broadcasts along contiguous memory and a weighted readout reduces
    over whole rows (faster on CPU than ``(S, *state)``, benchmarks/bench_ops.py).
    """
    T = _leading(xs)
    S = max(1, min(int(segments), T))
    L = -(-T // S)
    # (L, S, ...): row l holds sample l of every piece; piece s covers samples s*L .. s*L + L - 1
    xl = jax.tree_util.tree_map(lambda x: jnp.swapaxes(x.reshape(S, L, *x.shape[1:]), 0, 1), _pad_to(xs, S * L))
    if segment_axis_last:
        shape = (*y0.shape, S)
        to_layout = lambda v: jnp.moveaxis(v, 0, -1)
        from_layout = lambda v: jnp.moveaxis(v, -1, 0)
    else:
        shape = (S, *y0.shape)
        to_layout = from_layout = lambda v: v

    def step_elements(x):
        e = _broadcast_elements(elements(x), (S, *y0.shape))
        return jax.tree_util.tree_map(to_layout, e)

    def compose(acc, x):
        return monoid.combine(acc, step_elements(x)), None

    maps = jax.tree_util.tree_map(from_layout, jax.lax.scan(compose, monoid.identity(shape), xl)[0])

    def enter(y, e):
        return monoid.apply(e, y), y

    starts = to_layout(jax.lax.scan(enter, y0, maps)[1])  # state before each piece

    def step(y, x):
        y = monoid.apply(step_elements(x), y)
        return y, readout(from_layout(y))

    out = jax.lax.scan(step, starts, xl)[1]  # (L, S, ...)
    return jnp.swapaxes(out, 0, 1).reshape(S * L, *out.shape[2:])[:T]


def run(method: str, monoid: Monoid, elements, xs, y0, readout, *, block: int, segments: int):
    if method == "scan":
        return run_scan(monoid, elements, xs, y0, readout)
    if method == "assoc":
        return run_assoc(monoid, elements, xs, y0, readout)
    if method == "chunked":
        return run_chunked(monoid, elements, xs, y0, readout, block)
    if method == "segmented":
        return run_segmented(monoid, elements, xs, y0, readout, segments)
    raise ValueError(f"method must be one of 'auto', 'scan', 'assoc', 'chunked', 'segmented', got {method!r}")
