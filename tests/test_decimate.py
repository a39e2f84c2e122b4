"""Fit view of long Joule-driven records (block-RMS drive, block-end output)."""

import numpy as np
import pytest

import smafl_jax as sj
import smafl_jax.identify._decimate as _decimate  # private: monkeypatch target (DECIMATE_ABOVE, TARGET_SAMPLES), fit_view
from smafl_jax.identify import decimate_mask, decimate_record, fit_stride


def _thermal_numpy(u, dt, k1, k2):
    """Exact ZOH first-order lag from U^2, at rest at 0 (plain numpy loop)."""
    a, g, th, out = np.exp(-k1 * dt), k2 / k1, 0.0, np.empty(len(u))
    for k, uk in enumerate(u):
        th = a * th + (1 - a) * g * uk * uk
        out[k] = th
    return out


def test_block_rms_view_keeps_the_thermal_state_of_a_fast_pwm():
    dt, stride, k1, k2 = 0.01, 10, 0.05, 0.04
    t = np.arange(60_000) * dt
    duty = 0.5 + 0.4 * np.sin(2 * np.pi * t / 170.0)
    u = 3.0 * ((t * 37.0) % 1.0 < duty)  # 37 Hz PWM: sampling it every 10th sample would alias
    rec = sj.Record.from_arrays(t, u, np.zeros_like(u), input_name="voltage_V", output_name="displacement_mm")
    view = decimate_record(rec, stride)
    assert len(view) == 6000 and view.dt == pytest.approx(0.1) and view.time[0] == pytest.approx(t[stride - 1])
    full = _thermal_numpy(u, dt, k1, k2)[stride - 1 :: stride]
    dec = _thermal_numpy(view.u, view.dt, k1, k2)
    # heat per block is exact; the state at a block end is off by O(k1 * block) of the ripple only
    assert np.max(np.abs(dec - full)) < 2e-3 * np.ptp(full)
    naive = _thermal_numpy(u[stride - 1 :: stride], view.dt, k1, k2)  # sampling the PWM instead
    assert np.max(np.abs(naive - full)) > 10 * np.max(np.abs(dec - full))
    assert np.array_equal(decimate_mask(np.arange(25) % 2 == 0, 5), np.array([True, False, True, False, True]))


def test_stride_rule():
    assert fit_stride(9_000, 0.01) == 1  # short records at full rate
    assert fit_stride(120_000, 0.01) == 5  # 20 min at 100 Hz: stride capped at 5 (24 000 samples at 0.05 s)
    assert fit_stride(30_000, 0.04) == 5  # 20 min at 25 Hz -> 6000 samples at 0.2 s
    assert fit_stride(45_000, 0.02) == 5  # 15 min at 50 Hz: 8 by the target length, capped
    assert fit_stride(120_000, 0.1) == 2  # capped by the longest view sample time (0.25 s)
    assert fit_stride(120_000, 0.3) == 1


@pytest.mark.slow  # suite time (14 s): the block-RMS view and the stride rule stay in the default suite
def test_fit_record_uses_the_view_and_scores_at_full_rate(monkeypatch, tmp_path):
    from smafl_jax.report import fit_record

    monkeypatch.setattr(_decimate, "DECIMATE_ABOVE", 900)
    monkeypatch.setattr(_decimate, "TARGET_SAMPLES", 400)
    t = np.arange(1200) * 0.04
    u = 2.0 + 1.5 * np.sin(2 * np.pi * t / 30.0) * np.sin(2 * np.pi * t / 7.0)
    truth = sj.Cascade.from_range(float(u.max()))
    y = np.asarray(sj.simulate(truth, u, 0.04)) + 0.002 * np.random.default_rng(0).normal(size=t.size)
    rec = sj.Record.from_arrays(t, u, y, input_name="voltage_V", output_name="displacement_mm")
    _, doc, (train, val, yhat) = fit_record(
        rec, model="cascade", max_steps=0, refit=False, orientation="rises", thermal_start="steady", sees="voltage", memory="rule"
    )
    view = doc["settings"]["fit_view"]
    assert view["stride"] == 3 and view["n_samples"] == 400
    assert len(yhat) == len(rec) and doc["metrics"]["train"]["n_samples"] == int(train.sum())
    assert any("decimated by 3" in n for n in doc["notes"])
    static = sj.EUPI.from_range(float(u.min()), float(u.max()))
    assert _decimate.fit_view(rec, static, [train])[2] is None  # no thermal part: fitted at full rate
