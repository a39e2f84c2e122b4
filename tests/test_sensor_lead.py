"""Issue 14: the `sensor_lead` effect (a lead-lag pre-stage that undoes a slow input sensor).

Reference: a plain numpy loop of ``x'(k) = z(k) + (lead / tau) (x(k) - z(k))`` with the exact zero-order-hold
low-pass ``z``; lead = tau is the identity; with lead = the sensor's time constant it undoes a first-order sensor
lag (leaving the short filter); JSON round trip; gradients against finite differences; recovery of a sensor lag
from a synthetic record (known truth) by the diagnosis' fit.
"""

from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from reference import lag_loop

import smafl_jax as sj
from smafl_jax.effects import EFFECTS, ExtendedModel, SensorLag
from smafl_jax.effects.sensor_lead import SensorLead

ROOT = Path(__file__).resolve().parents[1]


def _lead_np(x, dt, lead, tau):
    """``x' = z + g (x - z)``: z the low-pass with tau, g the gain whose pole cancels a lag of time constant lead."""
    z = lag_loop(x, dt, tau)
    g = (np.exp(dt / tau) - 1.0) / (np.exp(dt / lead) - 1.0)
    return z + g * (x - z)


def _eff(lead, tau):
    return SensorLead(lead=jnp.asarray(lead), tau=jnp.asarray(tau))


@pytest.fixture(scope="module")
def eupi():
    return sj.load_model(ROOT / "datasets" / "truth.json").hysteresis


@pytest.fixture(scope="module")
def steps():
    """Noisy steps (a smoothing/sharpening filter is visible on them), sampled every 0.1 s."""
    r = np.random.default_rng(5)
    return np.repeat(r.uniform(0.0, 7.0, 25), 40) + 0.02 * r.standard_normal(1000)


def test_registered_and_documented():
    assert EFFECTS["sensor_lead"] is SensorLead and SensorLead.stage == "input"
    assert set(SensorLead.parameters) == {"lead", "tau"} == {p.field for p in SensorLead.nonlinear({"dt": 0.1})}


@pytest.mark.parametrize(("lead", "tau"), [(6.3, 1.7), (0.05, 2.0), (0.4, 0.03)])
def test_reference_loop(steps, lead, tau):
    dt = 0.1
    got = np.asarray(_eff(lead, tau).transform_input(jnp.asarray(steps), dt))
    ref = _lead_np(steps, dt, lead, tau)
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)
    assert got[0] == pytest.approx(steps[0], abs=1e-12)  # x'(0) = x(0)


def test_lead_equal_to_filter_is_identity(steps, eupi):
    for tau in (0.05, 1.0, 30.0):
        np.testing.assert_allclose(np.asarray(_eff(tau, tau).transform_input(jnp.asarray(steps), 0.1)), steps, atol=1e-12)
    y0 = np.asarray(sj.simulate(eupi, steps))
    y1 = np.asarray(sj.simulate(ExtendedModel(eupi, (_eff(2.5, 2.5),)), steps, 0.1))
    np.testing.assert_allclose(y1, y0, atol=1e-10)
    # a lead (or a partial lag) does change the hysteresis output
    assert np.max(np.abs(np.asarray(sj.simulate(ExtendedModel(eupi, (_eff(5.0, 1.0),)), steps, 0.1)) - y0)) > 0.1


def test_no_lead_is_sensor_lag(steps):
    """lead -> 0 leaves the low-pass alone: `sensor_lag` is the limit of this effect."""
    x = jnp.asarray(steps)
    lag = np.asarray(SensorLag(tau=jnp.asarray(3.0)).transform_input(x, 0.1))
    np.testing.assert_allclose(np.asarray(_eff(1e-12, 3.0).transform_input(x, 0.1)), lag, atol=1e-10)


def test_undoes_a_first_order_sensor_lag():
    """A slow sensor (time constant 4 s) reads a fast material temperature; the lead with the sensor's time constant
    gives the material temperature back through the short filter only (exactly: the poles cancel)."""
    dt, tau_s, tau_f = 0.1, 4.0, 0.3
    t = np.arange(0, 80, dt)
    # the material: smooth steps (1 s rise), a slow oscillation and sensor noise
    true = lag_loop(np.where((t > 10) & (t < 45), 60.0, 25.0), dt, 0.3) + 3.0 * np.sin(2 * np.pi * t / 17.0)
    sensor = lag_loop(true, dt, tau_s)
    want = lag_loop(true, dt, tau_f)
    span = np.ptp(true)
    got = np.asarray(_eff(tau_s, tau_f).transform_input(jnp.asarray(sensor), dt))
    assert np.max(np.abs(sensor - want)) > 0.5 * span  # the sensor lag is large
    np.testing.assert_allclose(got, want, atol=1e-9 * span)  # and undone, leaving the filter
    # sensor_lead after sensor_lag is sensor_lag with the filter's time constant
    lag = SensorLag(tau=jnp.asarray(tau_s)).transform_input(jnp.asarray(true), dt)
    np.testing.assert_allclose(np.asarray(_eff(tau_s, tau_f).transform_input(lag, dt)), want, atol=1e-9 * span)
    # a wrong lead time leaves a visible error; the continuous-time gain lead / tau is the dt -> 0 limit
    assert np.max(np.abs(np.asarray(_eff(0.7 * tau_s, tau_f).transform_input(jnp.asarray(sensor), dt)) - want)) > 0.05 * span
    g = lambda d: float(jnp.expm1(d / tau_f) / jnp.expm1(d / tau_s))
    assert abs(g(1e-4) - tau_s / tau_f) < 1e-3 * tau_s / tau_f < abs(g(dt) - tau_s / tau_f)


def test_json_round_trip(tmp_path, eupi, steps):
    m = ExtendedModel(eupi, (_eff(4.2, 0.7), SensorLag(tau=jnp.asarray(1.5))))
    sj.save_model(tmp_path / "lead.json", m)
    back = sj.load_model(tmp_path / "lead.json")
    assert back.effect_names == ["sensor_lead", "sensor_lag"]
    e = back.get("sensor_lead")
    assert isinstance(e, SensorLead) and float(e.lead) == 4.2 and float(e.tau) == 0.7
    np.testing.assert_allclose(np.asarray(sj.simulate(back, steps, 0.1)), np.asarray(sj.simulate(m, steps, 0.1)), atol=1e-12)


def test_gradient_matches_finite_differences(steps):
    x = jnp.asarray(steps[:300])
    w = jnp.asarray(np.random.default_rng(2).standard_normal(300))

    @eqx.filter_jit
    def loss(p):
        return jnp.sum(w * jnp.sin(0.3 * _eff(p[0], p[1]).transform_input(x, 0.1)))

    p0 = np.array([2.3, 0.6])
    g = np.asarray(jax.grad(loss)(jnp.asarray(p0)))
    fd = []
    for i in range(2):
        h = np.zeros(2)
        h[i] = 1e-6 * p0[i]
        fd.append((float(loss(jnp.asarray(p0 + h))) - float(loss(jnp.asarray(p0 - h)))) / (2 * h[i]))
    np.testing.assert_allclose(g, fd, rtol=1e-5)
    assert np.all(np.abs(g) > 1e-3)


def test_one_trace_for_new_parameter_values(steps):
    @eqx.debug.assert_max_traces(max_traces=1)
    def run(e, x):
        return e.transform_input(x, 0.1)

    run = eqx.filter_jit(run)
    for lead, tau in ((1.0, 0.5), (3.0, 0.2), (0.4, 2.0)):
        run(_eff(lead, tau), jnp.asarray(steps))


@pytest.mark.slow  # suite time (15 s): the lead stage, its gradient and reference loop stay in the default suite
def test_fit_recovers_a_sensor_lag(eupi):
    """Synthetic record with known truth: the EUPI sees the material temperature, the input column is a 3 s sensor
    lag of it; the diagnosis' fit of ``sensor_lead`` finds the lead time and beats the base model."""
    from smafl_jax.data import Record
    from smafl_jax.diagnosis import Split, fit_extended
    from smafl_jax.diagnosis._diagnose import _segment  # private: builds a diagnosis Segment (no public constructor)

    dt, tau_s = 0.1, 3.0
    r = np.random.default_rng(11)
    levels = np.r_[0.0, r.uniform(1.0, 7.0, 9), 0.0, r.uniform(0.5, 6.5, 9)]
    material = lag_loop(np.repeat(levels, 150), dt, 0.4)  # each step: 15 s, rises in ~1 s
    sensor = lag_loop(material, dt, tau_s)
    y = np.asarray(sj.simulate(eupi, material)) + 0.003 * r.standard_normal(material.size)
    rec = Record.from_arrays(np.arange(y.size) * dt, sensor, y, input_name="temperature_C", output_name="length")
    n = len(rec)
    split = Split("time", "test", [_segment(rec, np.arange(n), mask=np.arange(n) < n // 2)], [])
    base0 = sj.EUPI.from_range(float(sensor.min()), float(sensor.max()), u_ref=float(sensor.min()))
    m0, i0 = fit_extended(base0, [], split)
    m1, i1 = fit_extended(base0, ["sensor_lead"], split)
    e = m1.get("sensor_lead")
    assert float(e.lead) == pytest.approx(tau_s, rel=0.02)
    assert float(e.lead) > 3.0 * float(e.tau)  # a lead, with a short filter
    assert i1["train_sse"] < 0.1 * i0["train_sse"]
