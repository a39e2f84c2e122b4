import jax
import jax.numpy as jnp
import numpy as np
import pytest
from reference import eupi_loop, random_reversals, thermal_loop

import smafl_jax as sj


def random_eupi(rng, init="descended", method="scan"):
    m = sj.EUPI.from_range(0.0, 7.4, n_sym=5, n_alpha=3, n_asym=4, poly_order=4, init=init, method=method)
    theta = rng.uniform(0.05, 1.0, m.linear_weights().shape[0])
    theta[-4:] = rng.normal(size=4)  # polynomial and offset are free in sign
    return m.with_linear_weights(theta)


@pytest.mark.parametrize("init", ["descended", "zero"])
@pytest.mark.parametrize("method", ["scan", "assoc"])
def test_eupi_matches_numpy_loop(rng, init, method):
    m = random_eupi(rng, init, method)
    u = random_reversals(rng, 800)
    got = np.asarray(sj.simulate(m, u))
    assert np.max(np.abs(got - eupi_loop(m, u))) < 1e-12


def test_eupi_consistent_init_starts_from_rest(rng):
    m = random_eupi(rng, "consistent")
    u = random_reversals(rng, 50, lo=1.0)
    ops = np.asarray(m.operators(u))
    s0 = (u[0] - float(m.u_ref)) / float(m.u_span)
    r, a = (np.asarray(x) for x in m._bank())
    np.testing.assert_allclose(ops[0], np.maximum(s0 - r, np.minimum(a * (s0 + r), 0.0)))


def test_eupi_linear_weight_roundtrip(rng):
    m = random_eupi(rng)
    theta = np.asarray(m.linear_weights())
    m2 = m.with_linear_weights(theta)
    np.testing.assert_array_equal(np.asarray(m2.linear_weights()), theta)
    u = random_reversals(rng, 100)
    np.testing.assert_allclose(np.asarray(m.features(u) @ theta), np.asarray(sj.simulate(m, u)), rtol=0, atol=1e-12)
    assert m.nonnegative_columns().sum() == 1 + 5 + 12


def test_eupi_bad_configuration():
    with pytest.raises(ValueError, match="u_max > u_min"):
        sj.EUPI.from_range(3.0, 1.0)
    with pytest.raises(ValueError, match="init"):
        sj.EUPI.from_range(0.0, 1.0, init="warm")
    m = sj.EUPI.from_range(0.0, 1.0)
    with pytest.raises(ValueError, match="linear weights"):
        m.with_linear_weights(np.zeros(3))


def test_lag_settles_within_a_number_of_samples():
    """`settles_within`: the lag's time constant against ``samples`` samples of ``dt`` (auto's static-class gate)."""
    th = sj.JouleThermal(k1=jnp.asarray(0.019), k2=jnp.asarray(0.05))  # the SMA wing's fitted lag: 53 s
    assert not th.settles_within(10.0) and th.settles_within(10.0, samples=10.0)
    assert th.settles_within(10.0, 1.08) and not th.settles_within(10.0, 0.019, samples=5.0)


def test_thermal_matches_numpy_loop_and_exact_step(rng):
    th = sj.JouleThermal(k1=jnp.asarray(0.07), k2=jnp.asarray(0.05), init="ambient")
    u = rng.uniform(0, 7.4, 500)
    dt = 0.3
    got = np.asarray(sj.simulate(th, u, dt))
    assert np.max(np.abs(got - thermal_loop(u, dt, 0.07, 0.05, 0.0))) < 1e-12
    # constant input from ambient: the exact solution of the ODE at the sample instants
    U = 5.0
    t = dt * np.arange(1, 401)
    exact = 0.05 / 0.07 * U**2 * (1 - np.exp(-0.07 * t))
    np.testing.assert_allclose(np.asarray(sj.simulate(th, np.full(400, U), dt)), exact, rtol=1e-12)


def test_thermal_paper_defaults():
    th = sj.JouleThermal()
    assert float(th.k1) == pytest.approx(0.04988) and float(th.k2) == pytest.approx(0.04172)
    # steady init at the first input: a constant drive stays put
    out = np.asarray(sj.simulate(th, np.full(50, 3.0), 0.1))
    np.testing.assert_allclose(out, 0.04172 / 0.04988 * 9.0, rtol=1e-12)


def test_cascade_reduces_to_eupi_when_quasi_static(rng):
    eupi = random_eupi(rng)
    u = random_reversals(rng, 600)
    # fast thermal state: k1 dt >> 1 makes theta(k) = g U(k)^2 exactly
    fast = sj.Cascade(thermal=sj.JouleThermal(k1=jnp.asarray(200.0), k2=jnp.asarray(30.0)), hysteresis=eupi)
    diff = np.asarray(sj.simulate(fast, u, 1.0)) - np.asarray(sj.simulate(eupi, u))
    assert np.max(np.abs(diff)) < 1e-12
    # paper's thermal constants with a slow drive (period >> 20 s): close to the EUPI output
    t = np.arange(0, 20000.0, 1.0)
    u_slow = 3.7 + 3.6 * np.sin(2 * np.pi * t / 10000.0)
    slow = sj.Cascade(thermal=sj.JouleThermal(), hysteresis=eupi)
    y_c, y_e = np.asarray(sj.simulate(slow, u_slow, 1.0)), np.asarray(sj.simulate(eupi, u_slow))
    assert np.max(np.abs(y_c - y_e)) < 0.02 * (y_e.max() - y_e.min())


def test_grad_through_cascade_matches_finite_differences(rng):
    import equinox as eqx

    eupi = random_eupi(rng)
    u = random_reversals(rng, 400)
    base = sj.Cascade(thermal=sj.JouleThermal(k1=jnp.asarray(0.3), k2=jnp.asarray(0.2)), hysteresis=eupi)
    raw = sj.unconstrain(base)
    y_obs = np.asarray(sj.simulate(base, u, 0.5)) + 0.01 * rng.standard_normal(400)

    @eqx.filter_jit  # one compilation for the gradient's primal and the finite differences' calls (eager: 14 s)
    def loss(raw):
        return jnp.sum((sj.constrain(raw).simulate(u, 0.5) - y_obs) ** 2)

    g = jax.grad(loss)(raw)
    for path in (lambda m: m.thermal.k1, lambda m: m.thermal.k2, lambda m: m.hysteresis.gain, lambda m: m.hysteresis.alpha):
        leaf = np.asarray(path(raw), float)
        gl = np.atleast_1d(np.asarray(path(g)))
        for i in range(leaf.size):
            h = 1e-6
            e = np.zeros(leaf.size)
            e[i] = h
            plus = jax.tree_util.tree_map(lambda x: x, raw)
            lp = eqx.tree_at(path, raw, jnp.asarray((leaf.ravel() + e).reshape(leaf.shape)))
            lm = eqx.tree_at(path, raw, jnp.asarray((leaf.ravel() - e).reshape(leaf.shape)))
            fd = (loss(lp) - loss(lm)) / (2 * h)
            assert abs(gl[i] - fd) <= 1e-5 * max(1.0, abs(fd)), (i, gl[i], fd)
            del plus


def test_constrain_roundtrip_and_positive(rng):
    m = sj.Cascade.from_range(7.4)
    m = eqx_set_gains(m, rng)
    back = sj.constrain(sj.unconstrain(m))
    for a, b in zip(jax.tree_util.tree_leaves(m), jax.tree_util.tree_leaves(back)):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-9, atol=2 * sj.POSITIVE_FLOOR)
    mask = sj.positive_mask(m)
    assert mask.thermal.k1 and mask.hysteresis.v and not mask.hysteresis.poly and not mask.hysteresis.offset
    # any unconstrained values map to positive gains
    raw = jax.tree_util.tree_map(lambda x: x - 50.0, sj.unconstrain(m))
    assert float(sj.constrain(raw).hysteresis.gain) > 0


def eqx_set_gains(m, rng):
    h = m.hysteresis
    theta = rng.uniform(0.1, 1.0, h.linear_weights().shape[0])
    import equinox as eqx

    return eqx.tree_at(lambda c: c.hysteresis, m, h.with_linear_weights(theta))


def test_log_jacobian_matches_autodiff():
    th = sj.JouleThermal(k1=jnp.asarray(0.1), k2=jnp.asarray(0.2))
    raw = sj.unconstrain(th)
    # d softplus(x)/dx = sigmoid(x)
    expect = np.log(jax.nn.sigmoid(raw.k1)) + np.log(jax.nn.sigmoid(raw.k2))
    assert float(sj.log_jacobian(raw)) == pytest.approx(float(expect))


TRACES = []


class _CountingCascade(sj.Cascade):
    """Cascade whose Python body records each trace (it only runs while JAX traces)."""

    def simulate(self, u, dt):
        TRACES.append(u.shape)
        return super().simulate(u, dt)


def test_simulate_compiles_once_per_shape(rng):
    casc = _CountingCascade(thermal=sj.JouleThermal(), hysteresis=random_eupi(rng))
    TRACES.clear()
    for k in range(4):  # new data and a new dt each call: one trace only
        sj.simulate(casc, random_reversals(rng, 256), 0.1 * (k + 1))
    assert len(TRACES) == 1
    # new parameter values with the same structure do not retrace either
    casc2 = eqx_set_gains(casc, rng)
    sj.simulate(casc2, random_reversals(rng, 256), 0.5)
    assert len(TRACES) == 1
    # nor plain floats set by tree_at (a non-array leaf is static under filter_jit: it compiled once per value)
    import equinox as eqx

    for k1 in (0.03, 0.04, 0.05):
        sj.simulate(eqx.tree_at(lambda m: m.thermal.k1, casc, k1), random_reversals(rng, 256), 0.5)
    assert len(TRACES) == 1
    sj.simulate(casc, random_reversals(rng, 300), 0.5)  # a new shape compiles once more
    assert len(TRACES) == 2


def test_simulate_batch_shapes(rng):
    casc = sj.Cascade(thermal=sj.JouleThermal(), hysteresis=random_eupi(rng))
    u = np.stack([random_reversals(rng, 128) for _ in range(6)])
    out = sj.simulate_batch(casc, u, 0.5)
    assert out.shape == (6, 128)
    np.testing.assert_allclose(np.asarray(out[3]), np.asarray(sj.simulate(casc, u[3], 0.5)), atol=1e-13)
    with pytest.raises(ValueError, match="2-D"):
        sj.simulate_batch(casc, u[0], 0.5)
    with pytest.raises(ValueError, match="at least 2"):
        sj.simulate(casc, u[0, :1], 0.5)


def test_plain_numbers_become_trainable_arrays():
    """Python floats in a model must still be parameters (a float leaf would be silently frozen by fits)."""
    th = sj.JouleThermal(0.05, 0.04)
    assert isinstance(th.k1, jax.Array) and th.k1.dtype == jnp.float64
    spec = sj.default_trainable(sj.Cascade(th, sj.EUPI.from_range(0.0, 7.4)))
    assert spec.thermal.k1 is True and spec.thermal.k2 is False
    e = sj.EUPI.from_range(0.0, 7.4)
    e2 = type(e)(**{**{f: getattr(e, f) for f in e.__dataclass_fields__}, "offset": 1, "u_ref": 0})
    assert e2.offset.dtype == jnp.float64 and e2.u_ref.dtype == jnp.float64


def test_simulate_value_checks_under_jit(rng):
    """Values are checked inside the compiled function (equinox.error_if), not only at the Python level: traced
    values (here under an outer filter_jit) cannot be read before compiling (concrete ones: tests/test_api_input_checks.py)."""
    import equinox as eqx

    casc = sj.Cascade(thermal=sj.JouleThermal(), hysteresis=random_eupi(rng))
    u = random_reversals(rng, 64)
    bad = u.copy()
    bad[10] = np.nan
    with pytest.raises(eqx.EquinoxRuntimeError, match="NaN or inf"):
        eqx.filter_jit(sj.simulate)(casc, bad, jnp.asarray(0.5))
    with pytest.raises(eqx.EquinoxRuntimeError, match="dt must be > 0"):
        eqx.filter_jit(sj.simulate)(casc, u, jnp.asarray(-0.5))
    with pytest.raises(eqx.EquinoxRuntimeError, match="NaN or inf"):
        eqx.filter_jit(sj.simulate_batch)(casc, np.stack([u, bad]), jnp.asarray(0.5))
    assert np.all(np.isfinite(np.asarray(sj.simulate(casc, u, 0.5))))


def test_eupi_polynomial_continues_linearly_outside_its_range(rng):
    """Beyond the input range the model was built on, the polynomial goes on with its end value and slope (no cubic
    blow-up on a new run that leaves the fitted range); inside, it is the paper's powers.  Checked against the numpy
    reference on a record that leaves [0, 7.4] on both sides, in all three evaluation paths (simulate, features @
    weights, the per-sample step), and for value and slope continuity at both ends."""
    m = random_eupi(rng)
    u = np.concatenate([random_reversals(rng, 300), np.linspace(7.0, 12.0, 50), np.linspace(12.0, -3.0, 80)])
    want = eupi_loop(m, u)
    assert np.max(np.abs(np.asarray(sj.simulate(m, u)) - want)) < 1e-12
    assert np.max(np.abs(np.asarray(m.features(u) @ m.linear_weights()) - want)) < 1e-12
    _, ys = jax.lax.scan(lambda c, x: m.step(c, x), m.initial_state(u[0]), jnp.asarray(u))
    assert np.max(np.abs(np.asarray(ys) - want)) < 1e-12
    # far outside, the polynomial part grows linearly, not cubically: its value at 10x the span is a few poly units
    from smafl_jax.models._eupi import poly_columns  # private: the column rule itself

    s = jnp.asarray([-1e-7, 0.0, 1e-7, 1.0 - 1e-7, 1.0, 1.0 + 1e-7, 10.0])
    cols = np.asarray(poly_columns(s, 3))
    np.testing.assert_allclose(cols[6], [1 + 2 * 9.0, 1 + 3 * 9.0, 1 + 4 * 9.0])
    # continuity of value and slope at both ends (slopes from one-sided differences)
    np.testing.assert_allclose(cols[0], cols[1], atol=1e-12)
    np.testing.assert_allclose((cols[5] - cols[4]) / 1e-7, (cols[4] - cols[3]) / 1e-7, rtol=1e-5)
    np.testing.assert_allclose((cols[5] - cols[4]) / 1e-7, [2.0, 3.0, 4.0], rtol=1e-5)
    g = jax.grad(lambda x: jnp.sum(poly_columns(x, 3)))
    assert np.isfinite(float(g(jnp.asarray(1.0)))) and float(g(jnp.asarray(2.0))) == pytest.approx(9.0)


def test_weakly_typed_fields_do_not_recompile():
    """A field built from a Python number (``jnp.full(n, 0.5)`` is weakly typed) and the same field from a fit are one
    jit cache entry: the converter makes them strongly typed (a second compile of the LM solve cost 5-6 s)."""
    import equinox as eqx

    base = sj.EUPI.from_range(0.0, 1.0).with_fitted_memory(0.5)
    assert not base.memory.weak_type
    strong = base.with_fitted_memory(np.float64(0.5))
    assert not sj.JouleThermal(jnp.asarray(0.05), 0.04).k1.weak_type

    @eqx.filter_jit
    @eqx.debug.assert_max_traces(max_traces=1)
    def out(m):
        return m.simulate(jnp.linspace(0.0, 1.0, 20))

    np.testing.assert_allclose(out(base), out(strong))
