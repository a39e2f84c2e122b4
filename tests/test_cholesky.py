"""The posterior's pool-safe Cholesky (`smafl_jax.bayes._cholesky`): values against numpy / scipy, batches under vmap,
NaN for an indefinite matrix, and no LAPACK custom call left in the jitted log-density or predictions (batched under
vmap those deadlocked XLA's CPU thread pool: `smafl sample` hung for good on resumed chains, session 36)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg as sl

import smafl_jax as sj
from smafl_jax.bayes import _bayes  # private: the jitted log-density and predictions under test
from smafl_jax.bayes import _cholesky as chol  # private: the factorisation itself


@pytest.mark.parametrize("p", [1, 2, 7, 40])
def test_factor_and_solves_match_numpy_and_scipy(rng, p):
    a = rng.standard_normal((p + 3, p))
    m = a.T @ a + 0.05 * np.eye(p)
    b = rng.standard_normal(p)
    low = np.asarray(chol.cholesky(jnp.asarray(m)))
    np.testing.assert_allclose(low, np.linalg.cholesky(m), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(chol.solve_lower(jnp.asarray(low), jnp.asarray(b)), sl.solve_triangular(low, b, lower=True),
                               rtol=1e-10, atol=1e-12)  # fmt: skip
    np.testing.assert_allclose(chol.solve_lower_transpose(jnp.asarray(low), jnp.asarray(b)),
                               sl.solve_triangular(low.T, b, lower=False), rtol=1e-10, atol=1e-12)  # fmt: skip
    np.testing.assert_allclose(chol.cho_solve(jnp.asarray(low), jnp.asarray(b)), np.linalg.solve(m, b), rtol=1e-8, atol=1e-10)


def test_batched_under_vmap_and_nan_when_not_positive_definite(rng):
    ms = np.stack([(lambda a: a.T @ a + np.eye(5))(rng.standard_normal((8, 5))) for _ in range(6)])
    lows = jax.vmap(chol.cholesky)(jnp.asarray(ms))
    np.testing.assert_allclose(lows, np.linalg.cholesky(ms), rtol=1e-10, atol=1e-12)
    assert np.isnan(np.asarray(chol.cholesky(jnp.array([[1.0, 2.0], [2.0, 1.0]])))).any()


def _lapack_calls(hlo_text):
    return [ln for ln in hlo_text.splitlines() if "custom_call" in ln and "lapack" in ln.lower()]


@pytest.mark.parametrize("linear", ["marginalise", "profile"])
def test_the_jitted_posterior_calls_no_lapack(linear, rng):
    """The vmapped log-density and the posterior-predictive draws compile to plain XLA code: no LAPACK custom call."""
    n, dt = 60, 0.5
    u = 3.0 * (1.0 + np.sin(np.arange(n) * dt / 4.0))
    truth = sj.Cascade.from_range(6.0, n_sym=3, n_alpha=1, n_asym=2)
    y = np.asarray(sj.simulate(truth, u, dt)) + 0.01 * rng.standard_normal(n)
    post = sj.Posterior(truth, (u, y), dt, linear=linear, gain_scale=3.0, sigma=0.03)
    thetas = jnp.asarray(post.theta0 + 0.01 * rng.standard_normal((4, post.ndim)))
    keys = jax.random.split(jax.random.PRNGKey(0), 4)
    lp = _bayes._batch_log_prob.lower(post._d, thetas).as_text()
    pred = _bayes._batch_predict.lower(post._d, thetas, keys, jnp.asarray(u), jnp.asarray(dt)).as_text()
    assert _lapack_calls(jax.jit(jax.vmap(jnp.linalg.cholesky)).lower(jnp.ones((2, 3, 3))).as_text())  # the probe sees one
    assert not _lapack_calls(lp) and not _lapack_calls(pred)
    assert np.all(np.isfinite(np.asarray(_bayes._batch_log_prob(post._d, thetas))))
