"""The prior on the operator gains (`smafl_jax.identify._gain_prior`): MAP against a plain numpy solve, what it pulls in
and what it leaves alone, and the option's checks."""

import argparse

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.cli.fit import _gain_prior_arg  # private: the CLI's argument parser for --gain-prior
from smafl_jax.identify._gain_prior import check_gain_prior, map_gains  # private: the prior's own module


def _design(rng, n=2000, dead=True):
    """Columns: a ramp-like operator, a healthy second one, (a near-constant one), then the offset (ones)."""
    t = np.linspace(0.0, 1.0, n)
    u = 0.5 + 0.4 * np.sin(2 * np.pi * 3 * t) * t
    cols = [u, np.maximum(u - 0.3, 0.0)]
    if dead:
        cols.append(0.8 + 1e-5 * np.sin(2 * np.pi * 40 * t))  # barely moves: collinear with the offset
    A = np.column_stack([*cols, np.ones(n)])
    nonneg = np.array([True] * (A.shape[1] - 1) + [False])
    # the output has structure none of the columns explains (model error), as on real records
    y = 2.0 * u + 1.0 * cols[1] + 0.3 + 0.002 * np.sin(2 * np.pi * 40 * t + 1.2) + 0.01 * rng.standard_normal(n)
    return A, y, nonneg


def test_map_matches_a_plain_numpy_ridge_solve():
    rng = np.random.default_rng(0)
    A, y, nonneg = _design(rng, dead=False)
    x, info = map_gains(A, y, nonneg, 1.0)
    # reference: the same objective as stacked least squares (no bound is active here), plain numpy
    free, *_ = np.linalg.lstsq(A, y, rcond=None)
    sig2 = np.mean((A @ free - y) ** 2)
    p = np.where(nonneg, sig2 / np.ptp(y) ** 2, 0.0)
    ref, *_ = np.linalg.lstsq(np.vstack([A, np.diag(np.sqrt(p))]), np.concatenate([y, np.zeros(len(p))]), rcond=None)
    assert np.all(ref[nonneg] > 0)  # the reference is valid only if no bound is active
    np.testing.assert_allclose(x, ref, rtol=1e-6, atol=1e-9)
    assert info["sigma"] == pytest.approx(np.sqrt(sig2), rel=1e-6)


def test_prior_pulls_in_a_gain_that_cancels_the_offset_and_keeps_the_fit():
    rng = np.random.default_rng(1)
    A, y, nonneg = _design(rng, dead=True)
    x, info = map_gains(A, y, nonneg, 1.0)
    free_gain = info["largest_gain_free"]
    assert free_gain > 5 * np.ptp(y)  # least squares buys the last bit of error with a huge cancelling gain
    assert x[2] < 0.05 * free_gain  # the near-constant column's gain is pulled in
    assert info["rmse"] <= 1.05 * info["rmse_free"]  # at a small cost in training error
    # the prediction for a new run on which the near-constant operator sits elsewhere stays sane
    A_new = A.copy()
    A_new[:, 2] = 0.2
    free_x, *_ = np.linalg.lstsq(A, y, rcond=None)
    assert np.max(np.abs(A_new @ x - y)) < 0.1 * np.max(np.abs(A_new @ free_x - y))


def test_prior_leaves_gains_the_data_pin_down():
    rng = np.random.default_rng(2)
    A, y, nonneg = _design(rng, dead=False)
    x, info = map_gains(A, y, nonneg, 1.0)
    free_x, *_ = np.linalg.lstsq(A, y, rcond=None)
    np.testing.assert_allclose(x, free_x, rtol=2e-3)
    assert info["rmse"] == pytest.approx(info["rmse_free"], rel=1e-5)


def test_fit_with_gain_prior_on_a_clean_eupi_record():
    rng = np.random.default_rng(3)
    shape = sj.EUPI.from_range(0.0, 1.0, n_sym=4, n_alpha=2, n_asym=2, poly_order=2)
    nonneg = np.asarray(shape.nonnegative_columns())
    truth = shape.with_linear_weights(np.where(nonneg, rng.uniform(0.1, 1.0, nonneg.size), 0.2))
    t = np.arange(3000) * 0.01
    u = 0.5 + 0.45 * np.sin(2 * np.pi * 0.2 * t) * np.sin(2 * np.pi * 0.013 * t)
    y = np.asarray(sj.simulate(truth, u, 0.01)) + 1e-3 * rng.standard_normal(len(u))
    free = sj.fit(truth, (u, y), 0.01, solver=None)
    res = sj.fit(truth, (u, y), 0.01, solver=None, gain_prior=1.0)
    info = res.info["gain_prior"]
    assert info["kappa"] == 1.0 and info["rmse"] <= 1.01 * info["rmse_free"]
    y_free = np.asarray(sj.simulate(free.model, u, 0.01))
    y_map = np.asarray(sj.simulate(res.model, u, 0.01))
    assert np.sqrt(np.mean((y_map - y) ** 2)) <= 1.01 * np.sqrt(np.mean((y_free - y) ** 2))
    assert "gain_prior" not in (free.info or {})


@pytest.mark.parametrize("bad", [0, -1.0, float("nan"), float("inf"), "abc"])
def test_bad_gain_prior_is_refused(bad):
    with pytest.raises(ValueError, match="gain_prior"):
        check_gain_prior(bad)
    if isinstance(bad, str) or bad <= 0:
        with pytest.raises(argparse.ArgumentTypeError):
            _gain_prior_arg(str(bad))


def test_cli_gain_prior_values():
    assert _gain_prior_arg("none") is None
    assert _gain_prior_arg("2.5") == 2.5
    assert check_gain_prior(None) is None


@pytest.mark.parametrize(("wiggle", "weak"), [(5e-4, True), (5e-3, False)])
def test_a_column_that_barely_moves_gets_no_gain(wiggle, weak):
    """Below `WEAK_RTOL` x max|A| of movement a column's gain is 0, whatever trend it could explain (plant C r10: a
    gain near 50 on a column moving by 6e-5 of the span broke a new run); above it the data decide as before."""
    from smafl_jax.identify._gain_prior import WEAK_RTOL  # private: the threshold the test straddles

    rng = np.random.default_rng(3)
    n = 2000
    t = np.linspace(0.0, 1.0, n)
    u = 0.5 + 0.4 * np.sin(2 * np.pi * 3 * t) * t
    trend = np.sin(2 * np.pi * 0.7 * t)
    col = 0.8 + 0.5 * wiggle * trend
    A = np.column_stack([u, np.maximum(u - 0.3, 0.0), col, np.ones(n)])
    nonneg = np.array([True, True, True, False])
    y = 2.0 * u + np.maximum(u - 0.3, 0.0) + 0.3 + 0.02 * trend + 0.01 * rng.standard_normal(n)
    assert bool(np.ptp(col) <= WEAK_RTOL * np.max(np.abs(A))) == weak  # the design straddles the threshold as meant
    x, info = map_gains(A, y, nonneg, 1.0)
    free, *_ = np.linalg.lstsq(A, y, rcond=None)
    assert free[2] * 0.5 * wiggle == pytest.approx(0.02, rel=0.2)  # least squares explains the trend through that column
    if weak:
        assert x[2] == 0.0 and info["weak_columns"] == 1
        assert info["rmse"] > info["rmse_free"]  # the trend is left in the residual: the price of a sane gain
    else:
        assert x[2] * 0.5 * wiggle == pytest.approx(0.02, rel=0.2) and info["weak_columns"] == 0
