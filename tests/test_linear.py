"""The one linear solver (`smafl_jax.identify.linear.solve`) against numpy / scipy references."""

import itertools

import numpy as np
import pytest
import scipy.optimize

from smafl_jax.identify.linear import column_scale, solve


def _problem(rng, n=400, p=8, spread=6.0):
    """Columns of very different sizes (operator columns span orders of magnitude), offset last."""
    A = rng.normal(size=(n, p)) * 10.0 ** rng.uniform(-spread / 2, spread / 2, p)
    A[:, -1] = 1.0
    x = rng.uniform(-1.0, 1.0, p) / column_scale(A)
    return A, A @ x + 0.05 * rng.normal(size=n)


def test_unbounded_matches_lstsq(rng):
    A, b = _problem(rng)
    sol = solve(A, b)
    ref = np.linalg.lstsq(A, b, rcond=None)[0]
    np.testing.assert_allclose(sol.x, ref, rtol=1e-7, atol=1e-9 * np.max(np.abs(ref)))
    np.testing.assert_allclose(sol.loss, 0.5 * np.sum((A @ ref - b) ** 2), rtol=1e-10)


@pytest.mark.parametrize("method", ["bvls", "nnls"])
def test_nonneg_matches_scipy(rng, method):
    A, b = _problem(rng)
    b = b - 3.0 * A[:, 0] / column_scale(A)[0]  # push column 0 against its bound
    nonneg = np.r_[np.ones(A.shape[1] - 1, bool), False]
    sol = solve(A, b, nonneg, method=method)
    ref = scipy.optimize.lsq_linear(A, b, bounds=(np.where(nonneg, 0.0, -np.inf), np.inf), method="trf", tol=1e-14).x
    assert np.all(sol.x[nonneg] >= 0.0) and sol.x[0] == 0.0
    np.testing.assert_allclose(A @ sol.x, A @ ref, rtol=1e-6, atol=1e-6 * np.max(np.abs(A @ ref)))
    # KKT: zero gradient on free columns, non-negative gradient where clamped at 0
    g = A.T @ (A @ sol.x - b) * column_scale(A)
    tol = 1e-6 * np.max(np.abs(A.T @ b * column_scale(A)))
    free = ~nonneg | (sol.x > 0)
    assert np.all(np.abs(g[free]) < tol) and np.all(g[~free] > -tol)


def test_general_bounds(rng):
    A, b = _problem(rng, p=5)
    lo, hi = np.full(5, -0.1), np.full(5, 0.1)
    lo /= column_scale(A)
    hi /= column_scale(A)
    sol = solve(A, b, lower=lo, upper=hi)
    ref = scipy.optimize.lsq_linear(A, b, bounds=(lo, hi), method="trf", tol=1e-14).x
    assert np.all(sol.x >= lo) and np.all(sol.x <= hi)
    np.testing.assert_allclose(sol.loss, 0.5 * np.sum((A @ ref - b) ** 2), rtol=1e-8)
    with pytest.raises(ValueError, match="nnls"):
        solve(A, b, lower=lo, method="nnls")


def test_ridge_closed_form(rng):
    A, b = _problem(rng)
    n, p = A.shape
    s = column_scale(A)
    for ridge in (1e-3, 0.1, 10.0):
        As = A / s
        z = np.linalg.solve(As.T @ As + ridge * n * np.eye(p), As.T @ b)
        sol = solve(A, b, ridge=ridge, jitter=0.0)
        np.testing.assert_allclose(sol.x, z / s, rtol=1e-9)
    # ridge shrinks the scaled coefficients, monotonically
    norms = [np.linalg.norm(solve(A, b, ridge=r).x * s) for r in (0.0, 0.01, 1.0, 100.0)]
    assert all(a > c for a, c in itertools.pairwise(norms))


def test_penalty_closed_form_and_dof(rng):
    A, b = _problem(rng, p=6)
    D = np.diff(np.eye(6), axis=0)
    P = 50.0 * D.T @ D
    for scale in (True, False):
        sol = solve(A, b, penalty=P, scale=scale, jitter=0.0, dof=True)
        np.testing.assert_allclose(sol.x, np.linalg.solve(A.T @ A + P, A.T @ b), rtol=1e-8)
        H = A @ np.linalg.solve(A.T @ A + P, A.T)
        np.testing.assert_allclose(sol.dof, np.trace(H), rtol=1e-8)
    assert solve(A, b, jitter=0.0, dof=True).dof == pytest.approx(6.0, rel=1e-9)


@pytest.mark.parametrize("method", ["bvls", "nnls"])
def test_column_scaling_invariance(rng, method):
    """Rescaling a column rescales its coefficient inversely (ridge on scaled columns: unchanged fit)."""
    A, b = _problem(rng)
    nonneg = np.r_[np.ones(A.shape[1] - 1, bool), False]
    c = 10.0 ** rng.uniform(-5, 5, A.shape[1])
    for ridge in (0.0, 0.3) if method == "bvls" else (0.0,):
        x1 = solve(A, b, nonneg, ridge=ridge, method=method).x
        x2 = solve(A * c, b, nonneg, ridge=ridge, method=method).x
        np.testing.assert_allclose(x2 * c, x1, rtol=1e-7, atol=1e-9 * np.max(np.abs(x1)))


def test_drop_constant_and_clip(rng):
    n = 300
    u = np.sin(np.linspace(0, 6, n))
    A = np.column_stack([np.maximum(u - t, 0.0) for t in (-0.5, 0.0, 0.5, 2.0)] + [np.ones(n)])  # threshold 2.0 never reached
    b = A[:, :3] @ np.array([1.0, 2.0, 0.5]) + 0.3
    nonneg = np.r_[np.ones(4, bool), False]
    sol = solve(A, b, nonneg, drop_constant=True)
    assert sol.x[3] == 0.0
    np.testing.assert_allclose(sol.x[[0, 1, 2, 4]], [1.0, 2.0, 0.5, 0.3], atol=1e-8)
    assert np.all(solve(A, b, nonneg).x[nonneg] >= 0.0)  # clip=True: never a -1e-18 weight


def test_bad_input():
    A = np.ones((5, 2))
    with pytest.raises(ValueError, match="ridge"):
        solve(A, np.ones(5), ridge=-1.0)
    with pytest.raises(ValueError, match=r"\(n, p\)"):
        solve(A, np.ones(4))
    with pytest.raises(ValueError, match="method"):
        solve(A, np.ones(5), method="qr")
