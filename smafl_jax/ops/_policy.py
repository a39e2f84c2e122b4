"""Which evaluation form to use: `choose_method`, `default_segments`, `default_block`.

Placeholder thresholds; replaced by the measured ones below.
"""

from __future__ import annotations

import jax

__all__ = ["choose_method", "default_segments", "default_block", "METHODS"]

METHODS = ("scan", "assoc", "chunked", "segmented")


_ACCELERATORS = ("gpu", "cuda", "rocm", "tpu")


def _backend(backend):
    b = jax.default_backend() if backend is None else str(backend).lower()
    if b != "cpu" and b not in _ACCELERATORS:
        raise ValueError(f"backend must be 'cpu' or one of {_ACCELERATORS} (or None: jax.default_backend()), got {backend!r}")
    return b


def choose_method(T: int, n: int, backend: str | None = None) -> str:
    """Form for a record of ``T`` samples and a bank/state of ``n`` entries on ``backend``."""
    if _backend(backend) in _ACCELERATORS:
        if T <= 64:
            return "scan"
        return "assoc" if T <= 2**20 else "chunked"
    if n >= 32 and T >= 4096:
        return "segmented"
    return "scan"


def default_segments(T: int, n: int) -> int:
    return int(max(1, min(128, T // 16)))


def default_block(T: int, n: int, backend: str | None = None) -> int:
    if _backend(backend) in _ACCELERATORS:
        return int(min(T, 2**16))
    return int(min(T, 1024))
