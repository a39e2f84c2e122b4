"""One BLAS thread while the toolkit fits, for the command line and the Python API alike.

Why: the linear algebra of a fit is small (BVLS designs of a few dozen columns, Preisach grids of <= 631), while the
fit's own work runs on JAX's threads and on one thread per candidate class (`smafl_jax.report.choose_structure`).
OpenBLAS's worker threads spin while they wait and take the cores those threads need: on the 2-core machine the
benchmark fit of a 30 000-sample record took 107 s through the Python API with OpenBLAS's default threads and 61 s with
one, the same fit to the last digit (session 53; the command line has limited them since issue 16).
"""

from __future__ import annotations

import contextlib
import functools
import os
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


def one_blas_thread() -> contextlib.AbstractContextManager:
    """Context: every loaded BLAS library on one thread (threadpoolctl), restored on exit; nothing when the user set
    ``OPENBLAS_NUM_THREADS`` or threadpoolctl is missing.  The limit is process-wide while it lasts."""
    if user_chose_blas_threads():
        return contextlib.nullcontext()
    try:
        import scipy.linalg  # noqa: F401  (load SciPy's own OpenBLAS now, so that the limit reaches it too)
        from threadpoolctl import threadpool_limits
    except ImportError:
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def blas_limited(fn: F) -> F:
    """Decorator: ``fn`` runs under `one_blas_thread` (the public entry points that fit)."""

    @functools.wraps(fn)
    def wrapped(*args, **kwargs):
        with one_blas_thread():
            return fn(*args, **kwargs)

    return wrapped  # type: ignore[return-value]
