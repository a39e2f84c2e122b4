"""Baselines beside every fit (smafl_jax.identify._baselines): static polynomial and free-run first-order lag."""

import math

import numpy as np
import pytest

from smafl_jax import UserInputError
from smafl_jax.identify import (
    LAG_GRID,
    baselines_doc,
    compare_sentences,
    fit_lag_poly,
    fit_static_poly,
    is_voltage,
    score,
    tau_grid,
)


def lowpass_loop(s, dt, tau):
    """Plain-loop reference: x[0] = s[0], x[k] = a x[k-1] + (1 - a) s[k], a = exp(-dt / tau)."""
    a = math.exp(-dt / tau)
    x = np.empty_like(s)
    x[0] = s[0]
    for k in range(1, s.size):
        x[k] = a * x[k - 1] + (1 - a) * s[k]
    return x


def drive(rng, n=400, dt=0.1):
    t = dt * np.arange(n)
    return 2.5 + 2.0 * np.sin(2 * np.pi * t / rng.uniform(8, 15)) * np.exp(-t / 60) + 0.3 * rng.standard_normal(n).cumsum() / 20


def test_static_poly_matches_numpy_polyfit_on_training_samples(rng):
    u = rng.uniform(-1, 4, 300)
    y = 0.3 - 1.2 * u + 0.4 * u**2 - 0.05 * u**3 + 0.01 * rng.standard_normal(300)
    train = np.arange(300) < 200
    y_bad = y.copy()
    y_bad[~train] += 100.0  # held-out samples must not enter the fit
    sp = fit_static_poly([(u, y_bad, 0.1)], [train])
    ref = np.polynomial.polynomial.Polynomial.fit(u[train], y[train], 3)
    inside = (u >= u[train].min()) & (u <= u[train].max())  # outside it the cubic continues linearly (next test)
    np.testing.assert_allclose(sp.predict(u[inside]), ref(u[inside]), rtol=1e-9, atol=1e-9)
    held = ~train & inside
    m = score(sp, [(u, y, 0.1)], [held])
    err = y[held] - ref(u[held])
    assert m["rmse"] == pytest.approx(np.sqrt(np.mean(err**2)), rel=1e-8)
    assert m["e_r_percent"] == pytest.approx(np.max(np.abs(err)) / np.ptp(y[held]) * 100, rel=1e-8)


def test_polynomials_continue_linearly_outside_the_training_range(rng):
    """Beyond the trained input (or lag state) range a baseline's cubic goes on with its end value and slope, so a new
    run that leaves the range meets a straight line, not a cubic blow-up (a held-out lag state out of range predicted
    20 mm on a 4 mm stroke)."""
    u = rng.uniform(0.0, 2.0, 200)
    y = 1.0 + u - 0.8 * u**3 + 0.01 * rng.standard_normal(200)
    sp = fit_static_poly([(u, y, 0.1)])
    ref = np.polynomial.polynomial.Polynomial.fit(u, y, 3)
    lo, hi = float(u.min()), float(u.max())
    slope_hi, slope_lo = ref.deriv()(hi), ref.deriv()(lo)
    out = np.array([hi + 0.5, hi + 3.0, lo - 1.0])
    want = np.array([ref(hi) + 0.5 * slope_hi, ref(hi) + 3.0 * slope_hi, ref(lo) - 1.0 * slope_lo])
    np.testing.assert_allclose(sp.predict(out), want, rtol=1e-9, atol=1e-9)
    lag = fit_lag_poly([(u, y, 0.1)])
    x = lag.state(3.0 * u, 0.1)  # a drive three times the trained one: the state leaves the trained range
    assert x.max() > lag.hi
    p = lag.predict(3.0 * u, 0.1)
    above = x > lag.hi
    step = np.polynomial.polynomial.Polynomial(lag.coef)  # in the scaled coordinate z
    half = 0.5 * (lag.hi - lag.lo)
    np.testing.assert_allclose(p[above], step(1.0) + step.deriv()(1.0) * (x[above] - lag.hi) / half, rtol=1e-9)


@pytest.mark.parametrize("squared", [False, True])
def test_lag_poly_recovers_time_constant_and_matches_loop(rng, squared):
    dt = 0.1
    recs = []
    taus = tau_grid([(np.zeros(400), np.zeros(400), dt)])
    tau_true = float(taus[17])  # on the grid: recovered exactly when the data carry it
    for _ in range(2):
        u = drive(rng)
        x = lowpass_loop(u * u if squared else u, dt, tau_true)
        recs.append((u, 1.0 + 0.8 * x - 0.05 * x**2, dt))
    lag = fit_lag_poly(recs, squared=squared)
    assert lag.tau == pytest.approx(tau_true, rel=1e-12) and not lag.tau_at_grid_edge
    u0 = recs[0][0]
    np.testing.assert_allclose(lag.state(u0, dt), lowpass_loop(u0 * u0 if squared else u0, dt, tau_true), rtol=1e-12)
    assert score(lag, recs)["rmse"] < 1e-8 * np.ptp(recs[0][1])
    # a static polynomial cannot follow the lag
    assert score(fit_static_poly(recs), recs)["rmse"] > 100 * score(lag, recs)["rmse"]
    assert len(taus) == LAG_GRID and taus[0] == pytest.approx(dt) and taus[-1] == pytest.approx(399 * dt)


def test_lag_prediction_is_free_run_and_mask_respected(rng):
    dt = 0.1
    u = drive(rng)
    y = lowpass_loop(u, dt, 2.0)
    train = np.arange(u.size) < 250
    y_bad = y.copy()
    y_bad[~train] = -50.0
    taus = np.geomspace(0.1, 20.0, 15)
    a = fit_lag_poly([(u, y_bad, dt)], [train], taus=taus)
    b = fit_lag_poly([(u[:250], y[:250], dt)], taus=taus)
    assert a.tau == b.tau
    np.testing.assert_allclose(a.coef, b.coef, rtol=1e-9, atol=1e-9)
    # the prediction uses the input only: the measured output of the held-out part changes nothing
    np.testing.assert_array_equal(a.predict(u, dt), fit_lag_poly([(u, y, dt)], [train], taus=taus).predict(u, dt))


def test_baselines_doc_and_verdict(rng):
    u = rng.uniform(0, 5, 200)
    y = u**2
    train = np.arange(200) < 140
    poor = {"rmse": 1e3, "e_r_percent": 1e3, "max_abs_error": 1e3}
    doc = baselines_doc([(u, y, 1.0)], [train], [(u, y, 1.0)], [~train], squared=False, model_heldout=poor)
    assert set(doc["models"]) == {"static_poly", "first_order_lag"}
    sp = doc["models"]["static_poly"]
    assert sp["heldout"]["n_samples"] == 60 and sp["train"]["n_samples"] == 140 and sp["heldout"]["rmse"] < 1e-8
    # a poor model beats neither baseline
    assert all("does not beat" in s for s in doc["verdict"])
    bad = compare_sentences({"rmse": 2.0, "e_r_percent": 10.0}, {"static_poly": {"rmse": 1.0, "e_r_percent": 5.0}})
    assert bad == [bad[0]] and "the model does not beat baseline static_poly" in bad[0] and "ratio 2.00" in bad[0]
    win = compare_sentences({"rmse": 0.5, "e_r_percent": 10.0}, {"static_poly": {"rmse": 1.0, "e_r_percent": 5.0}})
    assert "beats" in win[0] and "does not" not in win[0] and "larger" in win[0]
    assert "no held-out" in compare_sentences(None, {})[0]


def test_voltage_detection_and_bad_input():
    assert is_voltage("voltage_V") and is_voltage("drive", {"drive": "V"}) and not is_voltage("temperature_front_C")
    # the symbols users give a drive voltage, and what must not count as one
    for name in ("U", "u", "V", "v_in", "Vset", "U_drive", "Spannung [V]", "drive (V)", "supply_volts"):
        assert is_voltage(name), name
    for name in ("x", "pressure", "displacement_mm", "tension_N", "velocity", "input", "uv", "level"):
        assert not is_voltage(name), name
    with pytest.raises(UserInputError, match="weight arrays"):
        fit_static_poly([(np.arange(5.0), np.arange(5.0), 1.0)], [None, None])
    with pytest.raises(UserInputError, match="no training samples"):
        fit_lag_poly([(np.arange(5.0), np.arange(5.0), 1.0)], [np.zeros(5)])
    with pytest.raises(UserInputError, match="sample time"):
        fit_static_poly([(np.arange(5.0), np.arange(5.0), 0.0)])
