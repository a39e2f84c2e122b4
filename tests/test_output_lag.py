"""Issue 13: the `output_lag` effect (the output sensor reads the actuator through a first-order lag).

Reference: a plain numpy loop of the zero-order-hold lag applied to the base model's output; constants pass unchanged
(the offset stays linear); JSON round trip; gradient against finite differences; one trace for new parameter values;
recovery of the lag from a synthetic record (known truth) by the diagnosis' fit, where an input lag does worse.
The blind diagnosis on the independent plant's output-lag records is an experiment (experiments/indep_effects.py truth
``output_lag``, experiments/diagnose_independent.py), not a test: a few minutes per record.
"""

from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from reference import lag_loop

import smafl_jax as sj
from smafl_jax.effects import EFFECTS, ExtendedModel, OutputLag

ROOT = Path(__file__).resolve().parents[1]


def _eff(tau):
    return OutputLag(tau=jnp.asarray(tau))


@pytest.fixture(scope="module")
def eupi():
    return sj.load_model(ROOT / "datasets" / "truth.json").hysteresis


@pytest.fixture(scope="module")
def steps():
    r = np.random.default_rng(7)
    return np.repeat(r.uniform(0.0, 7.0, 25), 40) + 0.02 * r.standard_normal(1000)


def test_registered_and_documented():
    assert EFFECTS["output_lag"] is OutputLag and OutputLag.stage == "features"
    ctx = {"dt": 0.04, "duration": 120.0, "n": 3000, "y_lo": 0.0, "y_hi": 1.0, "sign": 1.0}
    assert set(OutputLag.parameters) == {"tau"} == {p.field for p in OutputLag.nonlinear(ctx)}
    lo, hi = OutputLag.tau_bounds(ctx["dt"], ctx["duration"])
    assert lo == pytest.approx(0.01) and hi == pytest.approx(30.0)
    taus = [float(e.tau) for e in (*OutputLag.grid(ctx), *OutputLag.probes(ctx))]
    assert min(taus) >= 2 * lo and max(taus) <= 0.5 * hi and len(OutputLag.grid(ctx)) == 10
    # the transform maps the whole real line inside the bounds (a fit cannot run off to a record-long lag)
    (nl,) = OutputLag.nonlinear(ctx)
    assert lo < nl.transform.from_phi(-40.0) < nl.transform.from_phi(40.0) < hi * (1 + 1e-9)
    e, extra = OutputLag.synthesise(np.random.default_rng(0), ctx)
    assert 1.0 <= float(e.tau) <= 5.0 and extra == {}


@pytest.mark.parametrize("tau", [0.03, 0.7, 12.0])
def test_model_output_is_the_lagged_base_output(eupi, steps, tau):
    dt = 0.1
    y0 = np.asarray(sj.simulate(eupi, steps))
    got = np.asarray(sj.simulate(ExtendedModel(eupi, (_eff(tau),)), steps, dt))
    np.testing.assert_allclose(got, lag_loop(y0, dt, tau), rtol=1e-10, atol=1e-10)
    assert got[0] == pytest.approx(y0[0], abs=1e-12)  # at rest with the first sample


def test_constant_columns_pass_unchanged(steps):
    F = jnp.stack([jnp.ones(300), jnp.asarray(steps[:300])], axis=1)
    Z = np.asarray(_eff(2.0).filter_features(F, 0.1))
    np.testing.assert_allclose(Z[:, 0], 1.0, atol=1e-14)
    np.testing.assert_allclose(Z[:, 1], lag_loop(steps[:300], 0.1, 2.0), atol=1e-12)


def test_json_round_trip(tmp_path, eupi, steps):
    m = ExtendedModel(eupi, (_eff(1.3),))
    sj.save_model(tmp_path / "lag.json", m)
    back = sj.load_model(tmp_path / "lag.json")
    assert back.effect_names == ["output_lag"] and float(back.get("output_lag").tau) == 1.3
    np.testing.assert_allclose(np.asarray(sj.simulate(back, steps, 0.1)), np.asarray(sj.simulate(m, steps, 0.1)), atol=1e-12)


def test_gradient_matches_finite_differences(eupi, steps):
    x = jnp.asarray(steps[:300])
    w = jnp.asarray(np.random.default_rng(2).standard_normal(300))

    @eqx.filter_jit
    def loss(tau):
        return jnp.sum(w * sj.simulate(ExtendedModel(eupi, (_eff(tau),)), x, 0.1))

    t0 = 0.8
    g = float(jax.grad(loss)(jnp.asarray(t0)))
    h = 1e-6 * t0
    fd = (float(loss(jnp.asarray(t0 + h))) - float(loss(jnp.asarray(t0 - h)))) / (2 * h)
    assert g == pytest.approx(fd, rel=1e-5) and abs(g) > 1e-3


def test_one_trace_for_new_parameter_values(steps):
    @eqx.debug.assert_max_traces(max_traces=1)
    def run(e, F):
        return e.filter_features(F, 0.1)

    run = eqx.filter_jit(run)
    for tau in (0.2, 1.0, 7.5):
        run(_eff(tau), jnp.asarray(steps)[:, None])


def test_fit_recovers_an_output_lag(eupi):
    """Synthetic record with known truth: the EUPI's output read through a 1.5 s sensor lag; the diagnosis' fit of
    ``output_lag`` finds the time constant and beats the base model; ``sensor_lag`` (a lag of the input) does worse."""
    from smafl_jax.data import Record
    from smafl_jax.diagnosis import Split, fit_extended
    from smafl_jax.diagnosis._diagnose import _segment  # private: builds a diagnosis Segment (no public constructor)

    dt, tau = 0.1, 1.5
    r = np.random.default_rng(3)
    levels = np.r_[0.0, r.uniform(1.0, 7.0, 9), 0.0, r.uniform(0.5, 6.5, 9)]
    u = lag_loop(np.repeat(levels, 100), dt, 0.2)
    y = lag_loop(np.asarray(sj.simulate(eupi, u)), dt, tau) + 0.003 * r.standard_normal(u.size)
    rec = Record.from_arrays(np.arange(y.size) * dt, u, y, input_name="temperature_C", output_name="length")
    n = len(rec)
    split = Split("time", "test", [_segment(rec, np.arange(n), mask=np.arange(n) < n // 2)], [])
    base0 = sj.EUPI.from_range(float(u.min()), float(u.max()), u_ref=float(u.min()))
    _, i0 = fit_extended(base0, [], split)
    m1, i1 = fit_extended(base0, ["output_lag"], split)
    _, i2 = fit_extended(base0, ["sensor_lag"], split)
    assert float(m1.get("output_lag").tau) == pytest.approx(tau, rel=0.05)
    assert i1["train_sse"] < 0.1 * i0["train_sse"]
    assert i1["train_sse"] < 0.5 * i2["train_sse"]
