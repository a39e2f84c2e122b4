"""Pure recurrence kernels, each in a sequential and exact parallel-in-time forms.

Kernels are functions of arrays (no model classes), float64 and differentiable:

* `play` family - bank of (unparallel) play operators, eq. (1) of the paper, with
  optional weighted output and per-sample threshold scale;
* `relay` family - bank of Preisach relays, crisp or ramp;
* `affine` family - ``x(k) = a(k) x(k-1) + b(k)`` (thermal lag, sensor lag, creep), and `lowpass`.

Every family has a pure ``*_step`` for `jax.lax.scan` and four exact forms:
``*_scan`` (sequential), ``*_assoc`` (`jax.lax.associative_scan`), ``*_chunked``
(scan over blocks, associative inside: compile time independent of T) and
``*_segmented`` (pieces of the record in lockstep, the fastest exact CPU form for
wide banks); the unsuffixed function takes ``method=`` and defaults to
`choose_method`.  See `_engine` for the algorithms and `policy` for the measured
crossovers.
"""

from .. import _config  # noqa: F401  (x64)
from ._affine import affine, affine_assoc, affine_chunked, affine_scan, affine_segmented, affine_step, lowpass
from ._play import play, play_assoc, play_bounds, play_chunked, play_consistent_state, play_scan, play_segmented, play_step
from ._policy import METHODS, choose_method, default_block, default_segments
from ._relay import relay, relay_assoc, relay_bounds, relay_chunked, relay_scan, relay_segmented, relay_step

__all__ = [
    "METHODS",
    "affine",
    "affine_assoc",
    "affine_chunked",
    "affine_scan",
    "affine_segmented",
    "affine_step",
    "choose_method",
    "default_block",
    "default_segments",
    "lowpass",
    "play",
    "play_assoc",
    "play_bounds",
    "play_chunked",
    "play_consistent_state",
    "play_scan",
    "play_segmented",
    "play_step",
    "relay",
    "relay_assoc",
    "relay_bounds",
    "relay_chunked",
    "relay_scan",
    "relay_segmented",
    "relay_step",
]
