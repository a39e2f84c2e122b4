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
import os
from pathlib import Path

__all__ = ["map_count", "map_limit", "release_if_needed", "enable_persistent_cache", "persistent_cache_dir", "CACHE_ENV"]

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


# -- compiled programs kept on disk between runs ---------------------------------------------------------

#: Environment variable: "off" (or "0", "no") disables the on-disk cache of compiled programs that the command line
#: turns on; a path puts it there.  Unset: ``$XDG_CACHE_HOME/smafl-jax/xla`` (``~/.cache/smafl-jax/xla``).
CACHE_ENV = "SMAFL_COMPILE_CACHE"
#: Programs that compile faster than this are not written (JAX's default is 1 s; most of a fit's programs take 0.1-1 s).
MIN_COMPILE_S = 0.1


def persistent_cache_dir() -> str | None:
    """The folder of JAX's persistent compilation cache when one is in use, else None."""
    import jax

    return jax.config.jax_compilation_cache_dir or None


def enable_persistent_cache() -> str | None:
    """Turn on JAX's persistent compilation cache (`CACHE_ENV` says where, or off); returns its folder or None.

    Why: half of a default fit's time on a new process is compiling (the 30 000-sample benchmark record of issue 18:
    95 s, then 47.5 s for the same fit again in the same process).  With the programs on disk a second run (another
    record of the same length and structure, or the same one) skips most of it (session 26: 86.8 s -> 55.8 s).  A cache
    the user set for JAX (``JAX_COMPILATION_CACHE_DIR``) is kept as it is.  Results are unchanged: the same programs run.
    """
    import jax

    if persistent_cache_dir() is not None:
        return persistent_cache_dir()
    where = os.environ.get(CACHE_ENV)
    if where is not None and where.strip().lower() in ("off", "0", "no", "false", ""):
        return None
    if where is None:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        where = os.path.join(base, "smafl-jax", "xla")
    try:
        os.makedirs(where, exist_ok=True)
    except OSError as exc:
        _LOG.info("no on-disk cache of compiled programs (%s: %s)", where, exc)
        return None
    jax.config.update("jax_compilation_cache_dir", where)
    if "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS" not in os.environ:
        jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_S)
    return where
