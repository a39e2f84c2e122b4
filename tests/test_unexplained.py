"""Issue 13: the honest "unexplained" answer of the diagnosis (generic residual regression, `smafl_jax.diagnosis._unexplained`)."""

import json
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax import UserInputError
from smafl_jax.diagnosis import describe, expand_signals, generic_correction, lowpass, structure_verdict

ROOT = Path(__file__).resolve().parents[1]


def _drive(rng, n, dt):
    """Multi-level drive with ramps and holds (plain numpy)."""
    u = np.empty(n)
    k, level = 0, 0.5
    while k < n:
        new = rng.uniform(0.0, 1.0)
        ramp = int(rng.integers(5, 60))
        hold = int(rng.integers(20, 120))
        seg = np.r_[np.linspace(level, new, ramp), np.full(hold, new)]
        u[k : k + seg.size] = seg[: n - k]
        k += seg.size
        level = new
    return u


def _signals(rng, n=3000, dt=0.5):
    t = np.arange(n) * dt
    u = _drive(rng, n, dt)
    rate = np.gradient(u, dt)
    sig = {"input": u, "input_rate": rate, "direction": np.sign(rate), "elapsed_time": t, "nuisance": rng.standard_normal(n)}
    return t, sig


def _cut(sig, cut):
    return {k: v[:cut] for k, v in sig.items()}, {k: v[cut:] for k, v in sig.items()}


def test_lowpass_matches_a_loop():
    rng = np.random.default_rng(0)
    x = rng.standard_normal(200)
    dt, tau = 0.5, 3.0
    a = 1.0 - np.exp(-dt / tau)
    y = np.empty_like(x)
    y[0] = x[0]
    for k in range(1, x.size):
        y[k] = y[k - 1] + a * (x[k] - y[k - 1])
    np.testing.assert_allclose(lowpass(x, dt, tau), y, rtol=1e-12, atol=1e-12)
    ex = expand_signals({"input": x, "elapsed_time": np.arange(200.0)}, dt, (tau,))
    assert set(ex) == {"input", "elapsed_time", "lp3s:input"}  # time ramps are not filtered


def test_recovers_a_linear_residual_in_time_and_rate():
    """Residual = a t + b du/dt + noise: fitted on the first 70 %, the held-out RMSE drops to the noise level."""
    rng = np.random.default_rng(1)
    t, sig = _signals(rng)
    noise = 0.003
    r = 2e-5 * t + 0.4 * sig["input_rate"] + noise * rng.standard_normal(t.size)
    cut = int(0.7 * t.size)
    tr, te = _cut(sig, cut)
    out, arrays = generic_correction(tr, r[:cut], te, r[cut:], y_span_train=1.0, y_span_test=1.0)
    assert out["heldout_rmse_before"] > 5 * noise
    assert out["heldout_rmse_after"] < 1.1 * noise, out
    assert out["predictable"] and out["heldout_gain"] > 0.8
    assert out["heldout_e_r_after"] < out["heldout_e_r_before"]
    assert out["label"] == "generic residual regression (not a physical effect)"
    c = out["coefficients"]
    assert abs(c["elapsed_time"] - 2e-5) < 0.1 * 2e-5 and abs(c["input_rate"] - 0.4) < 0.05
    assert abs(c["nuisance"]) < 0.2 * noise
    manual = c["intercept"] + sum(c[k] * v for k, v in te.items())
    np.testing.assert_allclose(arrays["heldout_correction"], manual, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(arrays["heldout"], r[cut:])
    assert "structure left that no catalogue effect explains" in describe(True, out)


def test_white_noise_is_not_predictable():
    """Pure white noise: the CV picks a strong ridge, the held-out RMSE does not move, the summary says so."""
    rng = np.random.default_rng(2)
    t, sig = _signals(rng)
    r = 0.003 * rng.standard_normal(t.size)
    cut = int(0.7 * t.size)
    tr, te = _cut(sig, cut)
    out, _ = generic_correction(tr, r[:cut], te, r[cut:], y_span_train=1.0, y_span_test=1.0)
    assert out["ridge"] >= 1.0, out["ridge"]
    assert abs(out["heldout_gain"]) < 0.03 and not out["predictable"]
    assert "not predictable from these correlates" in describe(True, out)
    left, why = structure_verdict([], {"ljung_box": {"p_value": 0.4}}, {"signal": "input", "corr": 0.01, "p_value": 0.6})
    assert not left and "no significant structure" in why
    left, why = structure_verdict(["creep"], {"ljung_box": {"p_value": 1e-9}}, None)
    assert left and "after creep" in why and "not white" in why
    # on thousands of samples a fit at the noise floor fails the whiteness test too: detectable, not structure left
    left, why = structure_verdict([], {"ljung_box": {"p_value": 1e-40}}, None, heldout_noise_ratio=1.14)
    assert not left and "detectable but small" in why and "1.14x" in why
    left, why = structure_verdict([], {"ljung_box": {"p_value": 1e-40}}, None, heldout_noise_ratio=2.5)
    assert left and "not white" in why


def test_bad_inputs():
    rng = np.random.default_rng(3)
    _, sig = _signals(rng, n=400)
    tr, te = _cut(sig, 300)
    r = rng.standard_normal(400)
    with pytest.raises(UserInputError, match="samples"):
        generic_correction(tr, r[:299], te, r[300:])  # one sample short
    with pytest.raises(UserInputError, match="empty"):
        generic_correction({k: v[:0] for k, v in tr.items()}, r[:0], te, r[300:])
    with pytest.raises(UserInputError, match="held-out"):
        generic_correction(tr, r[:300], {k: v[:50] for k, v in te.items()}, r[300:])
    with pytest.raises(UserInputError, match="non-finite"):
        generic_correction(tr, np.r_[np.nan, r[1:300]], te, r[300:])
    with pytest.raises(UserInputError, match="too few"):
        generic_correction({k: v[:6] for k, v in tr.items()}, r[:6], te, r[300:])


def test_diagnose_reports_unexplained_without_changing_the_selection(tmp_path):
    """An extra column no catalogue effect uses moves the output: the key, the figure, the same selection."""

    from repo_scripts import load_script

    from smafl_jax.diagnosis import diagnose
    from smafl_jax.effects import ExtendedModel
    from smafl_jax.report import write_diagnosis

    drives = load_script("datasets/generate.py", "smafl_datasets_generate").drives()
    eupi = sj.load_model(ROOT / "datasets" / "truth.json").hysteresis
    u = np.concatenate([np.asarray(drives[k][1], float) for k in ("minor_loop", "main_loop")])
    dt = 0.5
    rng = np.random.default_rng(4)
    humidity = lowpass(rng.standard_normal(u.size), dt, 5.0)  # fluctuating faster than the drive: the base cannot soak it
    humidity = 50.0 + 10.0 * (humidity - humidity.mean()) / humidity.std()  # percent
    y = np.asarray(sj.simulate(ExtendedModel(eupi, ()), jnp.asarray(u), dt))
    y = y + 0.002 * (humidity - 50.0) + 0.003 * rng.standard_normal(u.size)  # 0.02 mm per 10 %: not in the catalogue
    rec = sj.Record.from_arrays(
        np.arange(u.size) * dt, u, y, input_name="temperature_C", output_name="displacement_mm", extra={"humidity": humidity}
    )
    kw = dict(effects=["strain_accumulation"], refit=False, verbose=False, n_null=3, seed=1, refine=False)
    diag = diagnose(rec, **kw)
    res, split = diag.report, diag.split
    diag0 = diagnose(rec, unexplained=False, **kw)
    res0 = diag0.report
    assert "unexplained" not in res0 and diag0.unexplained is None and diag0.residuals.correction is None
    assert diag.unexplained is res["unexplained"] and diag.residuals.correction is not None
    assert res["selected"] == res0["selected"]
    assert [c.get("decision") for c in res["candidates"]] == [c.get("decision") for c in res0["candidates"]]
    assert res["extended"]["heldout_rmse"] == res0["extended"]["heldout_rmse"]
    ux = res["unexplained"]
    assert ux["structure_left"] and ux["strongest_correlate"]["signal"] == "extra:humidity"
    c = ux["correction"]
    assert c["label"].startswith("generic residual regression")
    assert c["heldout_rmse_before"] == pytest.approx(res["extended"]["heldout_rmse"], rel=1e-9)
    # the held-out residual also holds the base model's own misfit (its weights soaked part of the humidity term in
    # training): the bar is what subtracting the true term would leave
    h = np.concatenate([s.extra["humidity"][s.mask] for s in split.test])
    oracle = np.sqrt(np.mean((diag.residuals.extended_heldout - 0.002 * (h - 50.0)) ** 2))
    assert c["heldout_rmse_after"] < min(1.5 * oracle, 0.7 * c["heldout_rmse_before"]) and c["predictable"], (oracle, c)
    assert next(iter(c["largest_terms_per_sd"])) == "extra:humidity" and c["coefficients"]["extra:humidity"] > 0
    write_diagnosis(tmp_path, rec, diag)
    doc = json.loads((tmp_path / "diagnosis.json").read_text())
    assert doc["unexplained"]["correction"]["heldout_rmse_after"] == pytest.approx(c["heldout_rmse_after"])
    assert (tmp_path / "residual_correction.png").stat().st_size > 0
    assert "Unexplained" in (tmp_path / "report.md").read_text()
