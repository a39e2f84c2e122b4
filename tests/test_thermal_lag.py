"""The drive's sampling convention (`JouleThermal.lag`): a plain numpy loop, the extended-model pipeline, the
closed loop's clear refusal, and bad configuration."""

import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.effects import ExtendedModel


def _loop_lag1(u, dt, k1, k2, theta0):
    """theta(k) = a theta(k-1) + (1 - a) g U(k-1)^2, U(-1) = U(0): the drive acts from the next sample."""
    a, g = np.exp(-k1 * dt), k2 / k1
    theta, prev, out = theta0, u[0], np.empty(len(u))
    for k, uk in enumerate(u):
        theta = a * theta + (1 - a) * g * prev * prev
        prev = uk
        out[k] = theta
    return out


@pytest.mark.parametrize("init", ["steady", "ambient"])
def test_lag1_matches_numpy_loop(rng, init):
    u = rng.uniform(0, 7.4, 400)
    th = sj.JouleThermal(k1=jnp.asarray(0.07), k2=jnp.asarray(0.05), init=init, lag=1)
    theta0 = 0.05 / 0.07 * u[0] ** 2 if init == "steady" else 0.0
    np.testing.assert_allclose(np.asarray(th.simulate(u, 0.3)), _loop_lag1(u, 0.3, 0.07, 0.05, theta0), rtol=1e-12, atol=1e-14)
    # lag 1 is lag 0 one sample later, with the first sample repeated
    th0 = dataclasses.replace(th, lag=0)
    np.testing.assert_allclose(np.asarray(th.simulate(u, 0.3)), np.asarray(th0.simulate(np.r_[u[0], u[:-1]], 0.3)), rtol=1e-13)


def test_extended_model_follows_the_lag(rng):
    """The effect pipeline runs its own thermal scan: it must apply the base's sampling convention too."""
    u = rng.uniform(0, 6.0, 300)
    for lag in (0, 1):
        cas = sj.Cascade(thermal=sj.JouleThermal(lag=lag), hysteresis=sj.EUPI.from_range(0.0, 6.0))
        np.testing.assert_allclose(
            np.asarray(ExtendedModel(cas, ()).simulate(u, 0.5)), np.asarray(cas.simulate(u, 0.5)), rtol=1e-10, atol=1e-12
        )


def test_bad_lag_and_closed_loop_refusal():
    with pytest.raises(ValueError, match="lag must be one of"):
        sj.JouleThermal(lag=2)
    cas = sj.Cascade(thermal=sj.JouleThermal(lag=1), hysteresis=sj.EUPI.from_range(0.0, 6.0))
    from smafl_jax.control import plant_init

    with pytest.raises(ValueError, match="next sample"):
        plant_init(cas, 1.0)


def test_lag_survives_the_model_file():
    from smafl_jax import model_from_dict, model_to_dict

    cas = sj.Cascade(thermal=sj.JouleThermal(lag=1), hysteresis=sj.EUPI.from_range(0.0, 6.0))
    assert model_from_dict(model_to_dict(cas)).thermal.lag == 1
