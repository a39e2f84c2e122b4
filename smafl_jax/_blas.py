"""One BLAS thread while the toolkit fits, for the command line and the Python API alike.

Why: the linear algebra of a fit is small (BVLS designs of a few dozen columns, Preisach grids of <= 631), while the
fit's own work runs on JAX's threads and on one thread per candidate class (`smafl_jax.report.choose_structure`).
OpenBLAS's worker threads spin while they wait and take the cores those threads need: on the 2-core machine the
benchmark fit of a 30 000-sample record took 107 s through the Python API with OpenBLAS's default threads and 61 s with
one, the same fit to the last digit (session 53; the command line has limited them since issue 16).  The public entry
points that fit carry `blas_limited`, `sj.fit` included.
"""

from __future__ import annotations

import contextlib
import functools
import os
import threading
from collections.abc import Callable
from typing import Any, TypeVar

F = TypeVar("F", bound=Callable[..., Any])

#: Set only by the command line when it writes ``OPENBLAS_NUM_THREADS=1`` itself (then it is not the user's choice).
_SET_BY_US = {"env": False}


def user_chose_blas_threads() -> bool:
    """True when ``OPENBLAS_NUM_THREADS`` was set by the user (their choice is kept, never overridden)."""
    return "OPENBLAS_NUM_THREADS" in os.environ and not _SET_BY_US["env"]


def set_blas_env() -> None:
    """``OPENBLAS_NUM_THREADS=1`` for BLAS libraries that load later (the command line, before NumPy loads)."""
    if not user_chose_blas_threads():
        os.environ["OPENBLAS_NUM_THREADS"] = "1"
        _SET_BY_US["env"] = True


# Entries into `one_blas_thread` across all threads: the first applies the limit, the last restores it.  Why a count:
# the limit is process-wide, and `sj.fit` runs inside the candidate threads of `choose_structure`, so each thread
# restoring "its" original setting on exit would hand BLAS its spinning workers back while another still fits.  (The
# OpenBLAS of SciPy's wheels, 0.3.31, also ignores a thread count set from any thread but the main one once the main
# thread has set one: the public entry points are normally entered there, which is where the limit takes effect.)
_DEPTH = {"n": 0, "limiter": None}
_LOCK = threading.Lock()


def _limit_now():
    try:
        import scipy.linalg  # noqa: F401  (load SciPy's own OpenBLAS now, so that the limit reaches it too)
        from threadpoolctl import threadpool_limits
    except ImportError:
        return None
    return threadpool_limits(limits=1, user_api="blas")


@contextlib.contextmanager
def one_blas_thread():
    """Context: every loaded BLAS library on one thread (threadpoolctl) from the first entry of any thread to the last
    exit, then restored; nothing when the user set ``OPENBLAS_NUM_THREADS`` or threadpoolctl is missing.  The limit is
    process-wide while it lasts."""
    if user_chose_blas_threads():
        yield
        return
    with _LOCK:
        if _DEPTH["n"] == 0:
            _DEPTH["limiter"] = _limit_now()
        _DEPTH["n"] += 1
    try:
        yield
    finally:
        with _LOCK:
            _DEPTH["n"] -= 1
            if _DEPTH["n"] == 0 and _DEPTH["limiter"] is not None:
                _DEPTH["limiter"].restore_original_limits()
                _DEPTH["limiter"] = None


def blas_limited(fn: F) -> F:
    """Decorator: ``fn`` runs under `one_blas_thread` (the public entry points that fit)."""

    @functools.wraps(fn)
    def wrapped(*args, **kwargs):
        with one_blas_thread():
            return fn(*args, **kwargs)

    return wrapped  # type: ignore[return-value]
