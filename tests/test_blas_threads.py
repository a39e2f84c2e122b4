"""The public entry points that fit run with one BLAS thread (`smafl_jax._blas`), as the command line does.

Why: through the Python API the benchmark fit took 107 s with OpenBLAS's default threads and 61 s with one on the
2-core machine (session 53); the command line had the limit already.  conftest.py holds every test process at one
thread, so each test here raises the limit first and checks what the entry point sees inside.
"""

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

import smafl_jax as sj
from smafl_jax import _blas  # private: the BLAS limit is an internal of every fitting entry point, tested here
from smafl_jax.report import choose_structure, fit_record


def _blas_threads_now():
    return {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}


def test_blas_limited_holds_one_thread_inside_and_restores_outside(monkeypatch):
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    monkeypatch.setitem(_blas._SET_BY_US, "env", False)
    seen = []
    with threadpool_limits(limits=2, user_api="blas"):
        _blas.blas_limited(lambda: seen.append(_blas_threads_now()))()
        after = _blas_threads_now()
    assert seen == [{1}]
    assert after == {2}


def test_the_limit_holds_until_the_last_thread_leaves(monkeypatch):
    """`sj.fit` runs inside the candidate threads: one thread leaving must not restore BLAS's threads while another
    still fits (the limit is process-wide).  A stand-in limiter records when the limit is applied and restored (this
    OpenBLAS ignores a thread count set from any thread but the main one once the main one has set it, so the real
    library cannot show the order here)."""
    import threading

    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    monkeypatch.setitem(_blas._SET_BY_US, "env", False)
    log = []

    class Limiter:
        def restore_original_limits(self):
            log.append("restored")

    monkeypatch.setattr(_blas, "_limit_now", lambda: log.append("limited") or Limiter())
    a_in, b_in, a_out = (threading.Event() for _ in range(3))

    def a():
        with _blas.one_blas_thread():
            a_in.set()
            b_in.wait(5)
        log.append("a left")
        a_out.set()

    def b():
        a_in.wait(5)
        with _blas.one_blas_thread():
            b_in.set()
            a_out.wait(5)
        log.append("b left")

    threads = [threading.Thread(target=f) for f in (a, b)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(10)
    assert log == ["limited", "a left", "restored", "b left"]


def test_the_users_own_blas_setting_is_kept(monkeypatch):
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "2")
    monkeypatch.setitem(_blas._SET_BY_US, "env", False)
    seen = []
    with threadpool_limits(limits=2, user_api="blas"):
        _blas.blas_limited(lambda: seen.append(_blas_threads_now()))()
    assert seen == [{2}]


@pytest.mark.parametrize("entry", [fit_record, choose_structure, sj.diagnose, sj.diagnose_records, sj.fit_many, sj.fit_records])
def test_public_fitting_entry_points_are_limited(entry):
    # the decorator keeps the signature and the docstring (help pages, option checks read them)
    assert getattr(entry, "__wrapped__", None) is not None
    assert entry.__doc__ == entry.__wrapped__.__doc__


def test_a_fit_through_fit_many_sees_one_blas_thread(monkeypatch):
    """End to end: the BVLS gains inside `sj.fit_many` run while BLAS is at one thread."""
    from smafl_jax.identify import varpro

    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    monkeypatch.setitem(_blas._SET_BY_US, "env", False)
    seen = []
    solve = varpro.solve_gains

    def spy(*args, **kwargs):
        seen.append(_blas_threads_now())
        return solve(*args, **kwargs)

    monkeypatch.setattr(varpro, "solve_gains", spy)
    t = np.arange(400) * 0.05
    u = 1.0 + 0.8 * np.sin(2 * np.pi * 0.1 * t)
    model = sj.EUPI.from_range(0.0, 2.0, n_sym=3, n_alpha=1, n_asym=1)
    y = np.asarray(sj.simulate(model, u, 0.05))
    with threadpool_limits(limits=2, user_api="blas"):
        sj.fit_many(model, [(u, y, 0.05)], init="linear", solver="varpro", max_steps=2, progress=False)
    assert seen, "the fit solved no gains: the spy never ran"
    assert all(s == {1} for s in seen)
