"""Keep the process under the kernel's memory-map limit while JAX compiles many programs.

XLA on CPU maps every compiled executable into memory in many small regions (about 70 maps per
executable), and JAX keeps every executable it compiled for the life of the process.  Linux caps a
process at ``vm.max_map_count`` maps (65 530 by default).  A diagnosis compiles a few hundred programs
(each candidate effect is a new model structure, each record length a new shape), so a script that
diagnoses records one after another in one process crossed the limit on its fourth record: XLA printed
"LLVM compilation error: Cannot allocate memory" and the process died with a segmentation fault
(measured: about 20 000 maps per 3 000-sample record with the default refinement).

`release_if_needed` is called at the entry of the long identification routines; when the process holds
more than `FRACTION` of the limit it clears JAX's caches (`jax.clear_caches`), which unmaps the
executables.  The price is recompiling what is used next; results are unchanged.
"""

from __future__ import annotations

import gc
import logging
from pathlib import Path

__all__ = ["map_count", "map_limit", "release_if_needed"]

_LOG = logging.getLogger(__name__)
#: Clear the caches once the process holds this fraction of ``vm.max_map_count``.
FRACTION = 0.5
_MAPS = Path("/proc/self/maps")
_LIMIT = Path("/proc/sys/vm/max_map_count")


def map_count() -> int | None:
    """Memory maps this process holds now (None where the platform does not say: not Linux)."""
    try:
        with _MAPS.open("rb") as f:
            return f.read().count(b"\n")
    except OSError:
        return None


def map_limit() -> int | None:
    """The kernel's per-process map limit (None where unknown)."""
    try:
        return int(_LIMIT.read_text().strip())
    except (OSError, ValueError):
        return None


def release_if_needed(fraction: float = FRACTION) -> bool:
    """Clear JAX's compilation caches when the process is above ``fraction`` of its map limit; True if cleared."""
    n, limit = map_count(), map_limit()
    if n is None or limit is None or n <= fraction * limit:
        return False
    import jax

    jax.clear_caches()
    gc.collect()
    _LOG.info("cleared JAX's compilation caches: %d of %d memory maps in use (now %s)", n, limit, map_count())
    return True
