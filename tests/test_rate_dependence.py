"""Issue 13: `rate_dependence` widens the play thresholds with the rate of the hysteresis input through a lag.

Reference: a plain numpy loop of the rate (sample difference over dt, times RATE_TIME), its first-order lag from rest
and the play operators with the thresholds scaled per sample; tau = 0 is the instantaneous rate of models saved before
the lag existed; finite gradients at tau = 0; the fit's starts lie inside the fitted range and include weak widening
(a start far above the record's own left the simplex worse than the base on independent records).
"""

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from reference import play_loop

import smafl_jax as sj
from smafl_jax.effects import RATE_TIME, ExtendedModel, RateDependence

ROOT = Path(__file__).resolve().parents[1]
DT = 0.25


@pytest.fixture(scope="module")
def eupi():
    return sj.load_model(ROOT / "datasets" / "truth.json").hysteresis


@pytest.fixture(scope="module")
def drive():
    r = np.random.default_rng(3)
    return np.repeat(r.uniform(0.0, 7.0, 20), 30) + 0.05 * r.standard_normal(600)


def _scale_loop(s, dt, c, tau):
    a = np.exp(-dt / tau) if tau > 0 else 0.0
    z, out, prev = 0.0, np.empty(len(s)), s[0]
    for k, sk in enumerate(s):
        z = a * z + (1.0 - a) * (sk - prev) / dt * RATE_TIME
        prev = sk
        out[k] = 1.0 + c * abs(z)
    return out


@pytest.mark.parametrize("tau", [0.0, 0.1, 2.0])
def test_threshold_scale_matches_numpy_loop(eupi, drive, tau):
    e = RateDependence(c=jnp.asarray(0.03), tau=jnp.asarray(tau))
    got = np.asarray(e.threshold_scale(jnp.asarray(drive), DT, eupi))
    s = (drive - float(eupi.u_ref)) / float(eupi.u_span)
    np.testing.assert_allclose(got, _scale_loop(s, DT, 0.03, tau), rtol=1e-12, atol=1e-12)


def test_operators_with_scaled_thresholds_match_numpy(eupi, drive):
    """The symmetric operators of the EUPI under the effect: numpy play steps with r(k) = r f(k)."""
    e = RateDependence(c=jnp.asarray(0.05), tau=jnp.asarray(1.0))
    f = np.asarray(e.threshold_scale(jnp.asarray(drive), DT, eupi))
    ops = np.asarray(eupi.operators(jnp.asarray(drive), jnp.asarray(f)))
    s = (drive - float(eupi.u_ref)) / float(eupi.u_span)
    r = np.asarray(eupi.r_sym, float)
    y0 = np.asarray(eupi.initial_state(jnp.asarray(drive[0] * 1.0)))[: len(r)]
    # one play step at a time with this sample's thresholds (play_loop on a single sample carries the state)
    y, ref = y0.copy(), np.empty((len(s), len(r)))
    for k in range(len(s)):
        y = play_loop(s[k : k + 1], r * f[k], 1.0, y)[0]
        ref[k] = y
    np.testing.assert_allclose(ops[:, : len(r)], ref, atol=1e-12)


def test_lag_is_optional_and_differentiable(eupi, drive):
    # a model saved before the lag existed (no tau) runs with the instantaneous rate
    old = RateDependence(c=jnp.asarray(0.05))
    assert float(old.tau) == 0.0
    m = ExtendedModel(eupi, (old,))
    y = np.asarray(sj.simulate(m, jnp.asarray(drive), DT))
    assert np.all(np.isfinite(y))

    def loss(tau):
        e = RateDependence(c=jnp.asarray(0.05), tau=tau)
        return jnp.sum(e.threshold_scale(jnp.asarray(drive), DT, eupi))

    for tau in (0.0, 1.5):
        g = float(jax.grad(loss)(jnp.asarray(tau)))
        assert np.isfinite(g)
    h = 1e-6
    fd = (float(loss(jnp.asarray(1.5 + h))) - float(loss(jnp.asarray(1.5 - h)))) / (2 * h)
    assert float(jax.grad(loss)(jnp.asarray(1.5))) == pytest.approx(fd, rel=1e-5)


def test_starts_inside_the_fitted_range_and_weak():
    for dt in (0.01, 0.25, 2.0):
        ctx = {"dt": dt, "duration": 600.0}
        lo, hi = RateDependence.tau_bounds(dt)
        starts = RateDependence.grid(ctx) + RateDependence.probes(ctx)
        taus = [float(e.tau) for e in starts]
        assert min(taus) >= 2 * lo and max(taus) <= 0.5 * hi
        assert min(float(e.c) for e in RateDependence.grid(ctx)) <= 0.003
        c_nl, tau_nl = RateDependence.nonlinear(ctx)
        assert lo <= tau_nl.transform.from_phi(-40.0) < tau_nl.transform.from_phi(40.0) <= hi * (1 + 1e-9)
