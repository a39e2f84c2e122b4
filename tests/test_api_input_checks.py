"""The Python API on bad input: `simulate` / `simulate_batch` / `fit` raise `UserInputError` naming the argument, the
shape or the first bad index before anything is compiled; a missing sample time is an error for a model whose output
depends on time; a joint refinement that does not lower the loss says so (message, info, log warning)."""

import logging

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from reference import eupi_loop, random_reversals, thermal_loop

import smafl_jax as sj

DT = 0.05


WEIGHTS = [0.2, 1.0, 0.5, 0.3, 0.1, 0.4, 0.0, 0.2, 0.1, 0.7, -0.3]
SMALL = dict(n_sym=4, n_alpha=2, n_asym=2, poly_order=2)


@pytest.fixture
def cascade():
    c = sj.Cascade.from_range(6.0, **SMALL)
    return c.with_hysteresis(c.hysteresis.with_linear_weights(jnp.asarray(WEIGHTS)))


@pytest.fixture
def eupi():
    return sj.EUPI.from_range(0.0, 5.0, **SMALL).with_linear_weights(jnp.asarray(WEIGHTS))


def test_simulate_needs_dt_for_a_model_that_depends_on_time(rng, cascade):
    u = random_reversals(rng, 80, 0.0, 6.0)
    for call in (lambda: sj.simulate(cascade, u), lambda: sj.simulate(cascade, u, None)):
        with pytest.raises(sj.UserInputError, match=r"dt \(the sample time in seconds\) is required.*Cascade") as e:
            call()
        assert "sj.simulate(model, u, 0.05)" in str(e.value)
    with pytest.raises(sj.UserInputError, match=r"sj\.simulate_batch\(model, u, 0\.05\)"):
        sj.simulate_batch(cascade, np.stack([u, u]))
    # the thermal stage alone needs it too; given, it is the one used (the numpy loop's at that dt)
    th = cascade.thermal
    with pytest.raises(sj.UserInputError, match="JouleThermal's output depends on time"):
        sj.simulate(th, u)
    want = thermal_loop(u, DT, float(th.k1), float(th.k2), float(th.initial_state(u[0])))
    assert np.max(np.abs(np.asarray(sj.simulate(th, u, DT)) - want)) < 1e-12
    assert not np.allclose(np.asarray(sj.simulate(cascade, u, DT)), np.asarray(sj.simulate(cascade, u, 1.0)))


def test_simulate_rate_independent_model_needs_no_dt(rng, eupi):
    """A hysteresis model on its own ignores time: dt may be left out, with the numpy loop's output."""
    u = random_reversals(rng, 120, 0.0, 5.0)
    got = np.asarray(sj.simulate(eupi, u))
    assert np.max(np.abs(got - eupi_loop(eupi, u))) < 1e-12
    np.testing.assert_array_equal(got, np.asarray(sj.simulate(eupi, u, 0.37)))


@pytest.mark.parametrize("k, value", [(0, np.nan), (17, np.inf), (79, -np.inf)])
def test_simulate_non_finite_input_names_the_first_bad_index(rng, cascade, k, value):
    u = random_reversals(rng, 80, 0.0, 6.0)
    u[k] = value
    if k != 79:
        u[79] = np.nan  # a later bad sample: the first one is named
    with pytest.raises(sj.UserInputError, match=rf"^u: the input is not finite at index {k} \(value {value}\)"):
        sj.simulate(cascade, u, DT)
    batch = np.stack([np.full(80, 1.0), u])
    with pytest.raises(sj.UserInputError, match=rf"not finite at index \(1, {k}\)"):
        sj.simulate_batch(cascade, batch, DT)


@pytest.mark.parametrize(
    "dt, match",
    [
        (-0.05, r"finite number of seconds > 0, got -0\.05"),
        (0.0, r"> 0, got 0\.0"),
        (np.nan, r"> 0, got nan"),
        (np.inf, r"> 0, got inf"),
        (np.array([0.05, 0.05]), r"must be a scalar, got shape \(2,\)"),
        ("50 ms", r"must be a number of seconds, got '50 ms'"),
    ],
)
def test_simulate_bad_dt(rng, cascade, dt, match):
    u = random_reversals(rng, 40, 0.0, 6.0)
    with pytest.raises(sj.UserInputError, match=r"^dt: the sample time .*" + match):
        sj.simulate(cascade, u, dt)


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda u: u[:, None], r"got shape \(40, 1\); a column \(N, 1\): pass u\[:, 0\]"),
        (lambda u: np.stack([u, u]), r"got shape \(2, 40\); for a batch of records \(B, T\) use sj\.simulate_batch"),
        (lambda u: 3.0, r"got shape \(\)"),
        (lambda u: u[:1], r"at least 2 samples, got 1"),
        (lambda u: "abc", r"expected an array of numbers, got str"),
    ],
)
def test_simulate_bad_shape(rng, cascade, make, match):
    u = random_reversals(rng, 40, 0.0, 6.0)
    with pytest.raises(sj.UserInputError, match=r"^u: .*" + match):
        sj.simulate(cascade, make(u), DT)


def test_simulate_batch_bad_shape(rng, cascade):
    with pytest.raises(sj.UserInputError, match=r"must be 2-D \(records, samples\), got shape \(40,\)"):
        sj.simulate_batch(cascade, random_reversals(rng, 40, 0.0, 6.0), DT)


def test_traced_values_keep_the_compiled_check(rng, cascade):
    """Inside a trace the values cannot be read in Python: the compiled function still refuses them."""
    u = random_reversals(rng, 40, 0.0, 6.0)
    bad = u.copy()
    bad[5] = np.nan
    traced = eqx.filter_jit(sj.simulate)
    with pytest.raises(eqx.EquinoxRuntimeError, match="NaN or inf"):
        traced(cascade, bad, jnp.asarray(DT))
    with pytest.raises(eqx.EquinoxRuntimeError, match="dt must be > 0"):
        traced(cascade, u, jnp.asarray(-DT))
    with pytest.raises(eqx.EquinoxRuntimeError, match="dt must be > 0"):
        jax.vmap(lambda d: sj.simulate(cascade, u, d))(jnp.asarray([DT, -DT]))
    ok = jax.vmap(lambda d: sj.simulate(cascade, u, d))(jnp.asarray([DT, 2 * DT]))
    np.testing.assert_allclose(np.asarray(ok[1]), np.asarray(sj.simulate(cascade, u, 2 * DT)), rtol=0, atol=1e-12)


def _pair(rng, n=60):
    u = random_reversals(rng, n, 0.0, 6.0)
    return u, 0.1 * u + 0.01 * rng.standard_normal(n)


def test_fit_needs_dt_for_plain_arrays(rng, cascade, eupi):
    u, y = _pair(rng)
    with pytest.raises(sj.UserInputError, match=r"^fit data 0: dt \(the sample time in seconds\) is required") as e:
        sj.fit(cascade, (u, y), solver=None)
    assert "sj.fit(model, (u, y), 0.05)" in str(e.value) and "Cascade" in str(e.value)
    with pytest.raises(sj.UserInputError, match="fit data 1: dt"):
        sj.fit(cascade, [(u, y, DT), (u, y)], solver=None)
    with pytest.raises(sj.UserInputError, match=r"dt .* is required"):
        sj.as_fit_data((u, y))  # no model named: plain arrays need their time
    # a Record carries its own sample time; a rate-independent model needs none
    rec = sj.Record.from_arrays(np.arange(u.size) * DT, u, y)
    assert sj.as_fit_data(rec)[0][2] == pytest.approx(DT)
    assert sj.fit(eupi, (u, y), solver=None).loss == pytest.approx(sj.fit(eupi, (u, y), 0.3, solver=None).loss, rel=1e-12)


@pytest.mark.parametrize(
    "data, match",
    [
        (lambda u, y: (np.stack([u, u]), y), r"fit data 0: the input u must be 1-D .*got shape \(2, 60\)"),
        (lambda u, y: (u[:, None], y), r"got shape \(60, 1\); one column \(N, 1\): pass u\[:, 0\]"),
        (lambda u, y: (u, y[:, None]), r"the output y must be 1-D .*pass y\[:, 0\]"),
        (lambda u, y: (u, y[:-10]), r"the input u has 60 samples but the output y has 50"),
        (lambda u, y: (u[:2], y[:2]), r"need at least 3 samples, got 2"),
        (lambda u, y: [u, y], r"fit data 0: expected a Record or a \(u, y\) / \(u, y, dt\) tuple, got ndarray of shape \(60,\)"),
        (lambda u, y: 3.0, r"^fit data: expected a Record, a \(u, y\) tuple"),
    ],
)
def test_fit_bad_shapes(rng, cascade, data, match):
    u, y = _pair(rng)
    with pytest.raises(sj.UserInputError, match=match):
        sj.fit(cascade, data(u, y), DT, solver=None)


@pytest.mark.parametrize("which", ["u", "y"])
def test_fit_non_finite_values_name_the_array_and_index(rng, cascade, which):
    u, y = _pair(rng)
    (u if which == "u" else y)[[7, 30]] = np.nan
    name = "input u" if which == "u" else "output y"
    with pytest.raises(sj.UserInputError, match=rf"fit data 0: the {name} is not finite at index 7 \(value nan\)"):
        sj.fit(cascade, (u, y), DT, solver=None)


@pytest.mark.parametrize("dt, match", [(-0.05, r"> 0, got -0\.05"), (0.0, r"> 0, got 0\.0"), (np.nan, "got nan")])
def test_fit_bad_dt(rng, cascade, dt, match):
    u, y = _pair(rng)
    with pytest.raises(sj.UserInputError, match=r"fit data 0: dt: the sample time .*" + match):
        sj.fit(cascade, (u, y), dt, solver=None)
    with pytest.raises(sj.UserInputError, match=r"fit data 0: dt: the sample time .*" + match):
        sj.fit(cascade, (u, y, dt), solver=None)


def _no_gain_lines(caplog):
    return [(r.levelno, r.getMessage()) for r in caplog.records if "did not lower the loss" in r.getMessage()]


@pytest.mark.slow  # suite time (15 s; a fresh-clone .ci/run took 612 s with it)
def test_refinement_that_does_not_lower_the_loss_says_so(rng, eupi, cascade, caplog):
    """A joint refinement that ends no lower than its start says so in ``message`` and ``info``; the log line is a
    WARNING when that is news: the refinement had something to do (here k2, which the output does not depend on), or
    the fit stays far above the output noise.  Gains from their own least squares at the noise: expected, INFO."""
    u = random_reversals(rng, 300, 0.0, 5.0)
    y = eupi_loop(eupi, u) + 0.01 * rng.standard_normal(u.size)
    fit_log = "smafl_jax.identify._fit"

    # gains only, from their bounded least squares, output at the noise: nothing to lower, said at INFO
    with caplog.at_level(logging.INFO, logger=fit_log):
        res = sj.fit(eupi, (u, y), init="linear", max_steps=5)
    assert res.init_loss > 0 and res.loss > res.init_loss * (1 - 1e-9)  # no gain beyond round-off
    assert res.info["refinement_lowered_loss"] is False and res.info["train_noise_ratio"] < 2
    assert "did not lower the loss below the initialiser's" in res.message and "least-squares optimum" in res.message
    assert [lv for lv, _ in _no_gain_lines(caplog)] == [logging.INFO]

    # the same far above the noise (a slow drift no EUPI has): a WARNING with the ratio and the way out
    caplog.clear()
    drift = y + 0.5 * np.sin(np.linspace(0.0, 2 * np.pi, u.size))
    with caplog.at_level(logging.INFO, logger=fit_log):
        poor = sj.fit(eupi, (u, drift), init="linear", max_steps=5)
    lines = _no_gain_lines(caplog)
    assert poor.info["train_noise_ratio"] > 2 and "x the output's noise SD" in poor.message
    assert [lv for lv, _ in lines] == [logging.WARNING] and "fit_record(sj.Record.from_arrays(t, u, y))" in lines[0][1]

    # ... but from the caller's own start (init=None, as the library's pipelines refine a screened start): INFO
    caplog.clear()
    with caplog.at_level(logging.INFO, logger=fit_log):
        again = sj.fit(poor.model, (u, drift), init=None, max_steps=5)
    assert again.info["refinement_lowered_loss"] is False and "did not lower" in again.message
    assert [lv for lv, _ in _no_gain_lines(caplog)] == [logging.INFO]

    # a trained parameter the initialiser does not solve (k2: a cascade's output does not depend on it): a WARNING
    caplog.clear()
    spec = eqx.tree_at(lambda s: (s.thermal.k1, s.thermal.k2), sj.default_trainable(cascade), (False, True))
    uc = random_reversals(rng, 300, 0.0, 6.0)
    yc = np.asarray(sj.simulate(cascade, uc, DT)) + 0.01 * rng.standard_normal(uc.size)
    with caplog.at_level(logging.INFO, logger=fit_log):
        k2 = sj.fit(cascade, (uc, yc), DT, init="linear", trainable=spec, max_steps=5)
    assert k2.info["refinement_lowered_loss"] is False and "least-squares optimum" not in k2.message
    assert [lv for lv, _ in _no_gain_lines(caplog)] == [logging.WARNING]

    # from gains away from their optimum the refinement does lower the loss: none of the above
    caplog.clear()
    off = eupi.with_linear_weights(0.5 * eupi.linear_weights())
    with caplog.at_level(logging.INFO, logger=fit_log):
        res = sj.fit(off, (u, y), init=None, max_steps=20)
    assert res.loss < res.init_loss and res.info["refinement_lowered_loss"] is True
    assert "did not lower" not in res.message and not _no_gain_lines(caplog)


def test_a_stack_of_models_is_refused_with_the_vmap_recipe(cascade):
    """`sj.stack_models` output passed to `sj.simulate` / `sj.simulate_batch`: a clear error that names the recipe (it
    failed deeper down with a message about a joint fit's record starts, or a broadcasting TypeError)."""
    import jax
    import jax.numpy as jnp

    models = sj.stack_models([cascade, cascade, cascade])
    u = np.linspace(0.0, 4.0, 50)
    with pytest.raises(sj.UserInputError, match=r"a stack of 3 models .*jax\.vmap\(sj\.simulate"):
        sj.simulate(models, u, 0.1)
    with pytest.raises(sj.UserInputError, match="a stack of 3 models"):
        sj.simulate_batch(models, np.stack([u, u]), 0.1)
    ys = jax.vmap(sj.simulate, in_axes=(0, None, None))(models, jnp.asarray(u), 0.1)  # the recipe works
    np.testing.assert_allclose(np.asarray(ys[1]), np.asarray(sj.simulate(cascade, u, 0.1)), rtol=1e-12, atol=1e-14)
