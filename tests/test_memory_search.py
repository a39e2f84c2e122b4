"""Per-operator search of a fitted operator memory (`search_memory`, `EUPI.memory_columns`, `linear.solve_gram`)."""

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.identify import default_trainable
from smafl_jax.identify._fit import init_linear  # private: the profiled gains the screening starts from
from smafl_jax.identify.linear import solve, solve_gram


def _np_play(s, r, a, y0):
    """Plain numpy loop of the (unparallel) play bank, state before the first sample ``y0``."""
    F = np.array(y0, dtype=float)
    out = np.empty((len(s), len(r)))
    for k, sk in enumerate(s):
        F = np.maximum(sk - r, np.minimum(a * (sk + r), F))
        out[k] = F
    return out


def _drive(rng, n=3000):
    """Random levels with ramps between them, in [0.2, 3.8]: operators move at different times."""
    levels = rng.uniform(0.2, 3.8, size=n // 150 + 1)
    x = np.repeat(levels, 150)[:n]
    return np.convolve(np.pad(x, (20, 0), mode="edge"), np.ones(21) / 21, mode="valid")[:n]


def _truth(rng, x, noise):
    """An EUPI off the default memory: every operator starts at its own random position between its bounds."""
    m = sj.EUPI.from_range(0.0, 4.0, n_sym=6, n_alpha=2, n_asym=3, poly_order=2)
    frac = rng.uniform(0.05, 0.95, m.n_operators)
    m = m.with_memory_fractions(frac)
    theta = np.concatenate([[0.3], rng.uniform(0.2, 1.0, m.n_operators), [0.05], [0.1]])
    m = m.with_linear_weights(theta)
    y = np.asarray(m.simulate(x)) + noise * rng.standard_normal(len(x))
    return m, frac, y


def test_memory_columns_match_a_numpy_loop_and_the_features(rng):
    x = _drive(rng, 800)
    m = sj.EUPI.from_range(0.0, 4.0, orientation=-1).with_fitted_memory(0.3)
    fr = rng.uniform(size=(4, m.n_operators))
    cols, C = m.memory_columns(x, fr)
    assert C.shape == (4, len(x), m.n_operators) and list(cols) == list(range(1, 1 + m.n_operators))
    s = np.asarray(m.normalise(x))
    r, a = (np.asarray(v) for v in m._bank())  # private: the bank's thresholds and tilts
    for k in range(4):
        ref = -_np_play(s, r, a, (s[0] - r) + fr[k] * (a * (s[0] + r) - (s[0] - r)))
        np.testing.assert_allclose(np.asarray(C[k]), ref, rtol=0, atol=1e-13)
        np.testing.assert_allclose(np.asarray(m.with_memory_fractions(fr[k]).features(x))[:, cols], ref, atol=1e-12)


def test_solve_gram_equals_the_tall_solve(rng):
    for p in (3, 8, 15):
        A = rng.normal(size=(400, p)) * np.logspace(-2, 2, p)
        b = A @ rng.normal(size=p) + rng.normal(size=400)
        nonneg = rng.uniform(size=p) < 0.6
        tall = solve(A, b, nonneg, jitter=0.0)
        gram = solve_gram(A.T @ A, A.T @ b, float(b @ b), nonneg, jitter=0.0)
        np.testing.assert_allclose(gram.x, tall.x, rtol=1e-7, atol=1e-9)
        assert gram.loss == pytest.approx(tall.loss, rel=1e-9)
        assert np.all(gram.x[nonneg] >= 0.0)


def test_solve_gram_survives_a_gram_matrix_made_indefinite_by_rounding(rng):
    """Two operators given the same start have equal columns; over 360 000 samples rounding left ``G`` indefinite beyond
    the jitter and the Cholesky factorisation raised (a default fit of a 60-min 100 Hz record stopped there)."""
    a, c = rng.uniform(size=500), rng.uniform(size=500)
    A = np.column_stack([a, a, c, np.ones(500)])
    b = A @ np.array([0.4, 0.4, 1.0, 0.2]) + 0.01 * rng.normal(size=500)
    v = np.array([1.0, -1.0, 0.0, 0.0]) / np.sqrt(2.0)
    G = A.T @ A - 1e-9 * float(np.trace(A.T @ A)) * np.outer(v, v)  # a negative eigenvalue, as rounding leaves one
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(G + 1e-12 * np.trace(G) / 4 * np.eye(4))
    nonneg = np.array([True, True, True, False])
    got = solve_gram(G, A.T @ b, float(b @ b), nonneg)
    tall = solve(A, b, nonneg)
    assert got.loss == pytest.approx(tall.loss, rel=1e-6, abs=1e-12)
    np.testing.assert_allclose(A @ got.x, A @ tall.x, atol=1e-6)
    assert np.all(got.x[nonneg] >= 0.0)


@pytest.mark.slow  # suite time (11 s): the memory search runs in the cascade start test below
def test_search_recovers_a_random_memory_that_uniform_starts_miss(rng):
    x = _drive(rng)
    truth, frac, y = _truth(rng, x, noise=0.002)
    data, w = [(x, y, 1.0)], [np.ones(len(x))]
    grid = truth.with_linear_weights(np.zeros_like(np.asarray(truth.linear_weights())))
    uniform = min(
        (init_linear(grid.with_fitted_memory(logit), data, weights=w) for logit in (5.0, 0.0, -5.0)),
        key=lambda m: float(np.sum((np.asarray(m.simulate(x)) - y) ** 2)),
    )
    sse_uniform = float(np.sum((np.asarray(uniform.simulate(x)) - y) ** 2))
    found, loss = sj.search_memory(uniform, data, w)
    assert loss == pytest.approx(0.5 * float(np.sum((np.asarray(found.simulate(x)) - y) ** 2)), rel=1e-9)
    assert 2.0 * loss < 0.25 * sse_uniform
    # the joint refinement from the searched start reaches the noise; from the best uniform start it does not
    spec = default_trainable(found)
    rmse = {}
    for name, start in (("searched", found), ("uniform", uniform)):
        res = sj.fit(start, data, weights=w, init=None, trainable=spec, max_steps=100)
        rmse[name] = float(np.sqrt(np.mean((np.asarray(res.model.simulate(x)) - y) ** 2)))
    assert rmse["searched"] < 1.3 * 0.002 < rmse["uniform"]


def test_search_only_where_the_memory_is_per_operator(rng):
    x = _drive(rng, 600)
    truth, _, y = _truth(rng, x, noise=0.002)
    data, w = [(x, y, 1.0)], [np.ones(len(x))]
    assert sj.search_memory(truth.with_init("descended"), data, w) is None  # a rule: nothing to search
    pre = sj.Preisach.from_range(0.0, 4.0, n_levels=8)
    assert pre.memory_columns(x, np.zeros((1, 3))) is None
    assert sj.search_memory(pre, data, w) is None
    with pytest.raises(ValueError, match="one fraction per operator"):
        truth.with_memory_fractions(np.full(3, 0.5))


@pytest.mark.slow  # suite time (session 70: 15-260 s on 2 cores)
def test_cascade_start_searches_memory_and_thermal_start_in_turn(rng):
    """A warm cascade record whose operators start at random positions: the screening's fitted-memory start
    (`fitted_memory_start`) is the searched one, below every common start, with the thermal rate near the truth."""
    n, dt = 2500, 0.1
    u = np.repeat(rng.uniform(0.3, 3.5, n // 100 + 1), 100)[:n]
    hyst = sj.EUPI.from_range(0.0, 3.5, n_sym=6, n_alpha=2, n_asym=3, poly_order=2)
    hyst = hyst.with_memory_fractions(rng.uniform(0.05, 0.95, hyst.n_operators))
    hyst = hyst.with_linear_weights(np.concatenate([[0.2], rng.uniform(0.2, 1.0, hyst.n_operators), [0.05], [0.0]]))
    truth = sj.Cascade(thermal=sj.JouleThermal(k1=0.05, init="given", u0=3.0), hysteresis=hyst)
    y = np.asarray(truth.simulate(u, dt)) + 0.002 * rng.standard_normal(n)
    data, w = [(u, y, dt)], [np.ones(n)]
    # the screening's own start: the truth's structure at a wrong thermal rate and start, memory untrained
    start = sj.Cascade(thermal=sj.JouleThermal(k1=0.035, init="given", u0=2.5), hysteresis=hyst.with_fitted_memory())
    start = init_linear(start, data, weights=w)
    common = min(
        float(
            np.sum(
                (np.asarray(init_linear(start.with_hysteresis(hyst.with_fitted_memory(lg)), data, weights=w).simulate(u, dt)) - y)
                ** 2
            )
        )
        for lg in (5.0, 0.0, -5.0)
    )
    got, label = sj.identify.fitted_memory_start(start, data, w)
    assert label == "searched"
    sse = float(np.sum((np.asarray(got.simulate(u, dt)) - y) ** 2))
    assert sse < 0.5 * common
    assert abs(float(got.thermal.k1) / 0.05 - 1.0) < abs(0.035 / 0.05 - 1.0)
