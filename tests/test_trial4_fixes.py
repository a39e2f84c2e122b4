"""Session 38 new-user trial 4: the noise floor of resampled records, range-warning times, and what --calibrate says.

1. `noise_floor` of a resampled `Record` leaves out the samples interpolated across its gaps (a straight line has no
   noise: a burst-sampled record read the floor 2x low).
2. Range and branch warnings give times on the record's own time axis (a record starting at 1000 s).
3. `recalibrate` / `simulate_record(calibrate=)`: a refinement that did not converge is said, the at-bound warning is
   said once, a calibration no better on its own segment is said, and so is a re-anchored output that scores worse
   than the raw one after the segment.
"""

import dataclasses
import logging
import re
from pathlib import Path

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.identify import after_segment_metrics
from smafl_jax.models import branch_check, range_check, trained_branches

DATASETS = Path(__file__).resolve().parents[1] / "datasets"
DT = 0.5


@pytest.fixture(scope="module")
def truth():
    return sj.load_model(DATASETS / "truth.json")


def _drive(n=420, top=7.4):
    """Triangular cycles of shrinking amplitude starting at 0 V (as tests/test_recalibrate.py)."""
    k = np.arange(n)
    phase = (k % 140) / 140
    amp = top * np.array([1.0, 0.75, 0.55])[np.minimum(k // 140, 2)]
    return amp * (1.0 - np.abs(2.0 * phase - 1.0))


# -- 1. noise floor on resampled records ------------------------------------------------------------------


def _burst_csv(path, rng, sd, n_bursts=300, burst=10, missing=3, dt=0.01):
    """Bursts of ``burst`` samples on a ``dt`` grid with ``missing`` grid points left out between them (a logger that
    writes in bursts), output = smooth motion + white noise of SD ``sd``; the record's grid points outside the gaps are
    then the measured samples themselves."""
    k = np.concatenate([b * (burst + missing) + np.arange(burst) for b in range(n_bursts)])
    t = k * dt
    u = 3.0 + 2.0 * np.sin(0.4 * t)
    y = np.sin(0.3 * t) + 0.2 * np.sin(1.1 * t) + sd * rng.standard_normal(t.size)
    sj.atomic_write_csv(path, {"time_s": t, "voltage_V": u, "displacement_mm": y})
    return path


def test_noise_floor_of_a_resampled_record_leaves_the_interpolated_samples_out(tmp_path):
    rng = np.random.default_rng(38)
    sd = 0.01
    rec = sj.load_record(_burst_csv(tmp_path / "bursts.csv", rng, sd), resample=0.01)
    assert rec.gaps  # the loader bridged the bursts' gaps
    t = rec.time
    inside = np.zeros(t.size, bool)
    tol = 1e-6 * rec.dt  # a grid point on a written stamp (0.07 read, 7 x 0.01 on the grid) is that stamp
    for a, b in rec.gaps:
        inside |= (t > a + tol) & (t < b - tol)
    assert 0.15 < inside.mean() < 0.3
    whole = sj.noise_floor([rec.y])  # the array alone: straight lines through the gaps pull the MAD down
    # the grid's rule (a record without its stamps as read; with them, tests/test_stamps_as_read.py)
    nf = sj.noise_floor([dataclasses.replace(rec, as_read=None)], train={"rmse": 0.02})
    assert sj.noise_floor([rec])["sd"] == pytest.approx(sd, rel=0.15)
    assert whole["sd"] < 0.8 * sd
    assert 0.85 < nf["sd"] / sd < 1.15
    assert nf["n_interpolated_left_out"] == int(inside.sum())
    assert "interpolated across gaps are left out" in nf["method"]
    assert nf["train_ratio"] == pytest.approx(0.02 / nf["sd"], rel=1e-12)
    # a record read as written is estimated as before, and says nothing about interpolation
    plain = sj.Record.from_arrays(np.arange(500) * 0.1, np.zeros(500), rec.y[:500])
    assert sj.noise_floor([plain]) == sj.noise_floor([rec.y[:500]])
    assert "n_interpolated_left_out" not in sj.noise_floor([plain])


def test_simulate_scores_a_resampled_record_against_the_noise_of_its_measured_samples(truth, tmp_path):
    rng = np.random.default_rng(5)
    sd = 0.01
    rec = sj.load_record(_burst_csv(tmp_path / "bursts.csv", rng, sd, n_bursts=120), resample=0.01)
    res = sj.simulate_record(truth, rec, measured="displacement_mm")
    noise = res.scores["noise"]
    assert noise["n_records_on_stamps_as_read"] == 1 and 0.8 < noise["sd"] / sd < 1.2
    assert noise["scored_ratio"] == pytest.approx(res.scores["rmse"] / noise["sd"], rel=1e-12)


def test_noise_floor_leaves_blank_cells_out_instead_of_returning_nan():
    rng = np.random.default_rng(1)
    y = np.sin(np.arange(3000) * 0.01) + 0.02 * rng.standard_normal(3000)
    holed = y.copy()
    holed[[10, 11, 500, 2999]] = np.nan
    nf = sj.noise_floor([holed])
    assert np.isfinite(nf["sd"]) and nf["sd"] == pytest.approx(sj.noise_floor([y])["sd"], rel=0.05)


# -- 2. range warnings on the record's own time axis ------------------------------------------------------


def test_range_check_times_start_at_the_first_sample_time():
    u = np.r_[np.linspace(0.0, 4.0, 10), np.full(5, 5.0), np.linspace(4.0, 0.0, 10)]
    at0 = range_check(u, [0.0, 4.0], "v", dt=0.5)
    shifted = range_check(u, [0.0, 4.0], "v", dt=0.5, t0=1000.0)
    assert at0["exits"][0]["start_s"] == pytest.approx(5.0)
    assert shifted["exits"][0]["start_s"] == pytest.approx(1005.0)
    assert shifted["exits"][0]["duration_s"] == at0["exits"][0]["duration_s"]
    assert "first at 1005 s for 2.5 s" in shifted["warning"] and "the longest at 1005 s" in shifted["warning"]
    assert "first at 5 s for 2.5 s" in at0["warning"]
    # without a sample time: sample indices, whatever t0
    assert "first at sample 10 for 5 samples" in range_check(u, [0.0, 4.0], t0=1000.0)["warning"]


def test_branch_check_times_start_at_the_first_sample_time():
    rising = np.linspace(0.0, 1.0, 200)
    trained = trained_branches(rising)
    falling = np.r_[rising, rising[::-1]]
    at0 = re.search(r"first at ([0-9.]+) s", branch_check(falling, trained, dt=0.1)["warning"])
    shifted = re.search(r"first at ([0-9.]+) s", branch_check(falling, trained, dt=0.1, t0=1000.0)["warning"])
    assert 20.0 <= float(at0.group(1)) < 40.0  # on the way back down, after the 20 s rise
    assert float(shifted.group(1)) == pytest.approx(float(at0.group(1)) + 1000.0, abs=1e-6)


def test_simulate_warns_with_the_record_time_axis(truth, tmp_path):
    model = tmp_path / "narrow.json"
    x = np.asarray(truth.hysteresis_input(np.linspace(0.0, 2.0, 400), DT))
    data = {"input_column": "voltage_V", "output_column": "displacement_mm", "input_range": [0.0, 2.0]}
    sj.save_model(model, truth, data={**data, "effective_input_range": [float(x.min()), float(x.max())]})
    u = _drive(200)
    t = np.arange(u.size) * DT
    runs = {}
    for t0 in (0.0, 1000.0):
        csv = tmp_path / f"rec_{t0:g}.csv"
        sj.atomic_write_csv(csv, {"time_s": t0 + t, "voltage_V": u})
        runs[t0] = sj.simulate_record(model, csv)
    for k in (0, 1):  # the raw input's and the hysteresis input's checks
        a, b = runs[0.0].range_checks[k], runs[1000.0].range_checks[k]
        assert [e["start_sample"] for e in a["exits"]] == [e["start_sample"] for e in b["exits"]]
        for ea, eb in zip(a["exits"], b["exits"]):
            assert eb["start_s"] == pytest.approx(ea["start_s"] + 1000.0, abs=1e-6)
    first = runs[1000.0].range_checks[0]["exits"][0]
    assert first["start_s"] == pytest.approx(1000.0 + first["start_sample"] * DT)
    warned = next(w for w in runs[1000.0].warnings if w.startswith("input 'voltage_V' leaves the range"))
    assert f"first at {first['start_s']:.6g} s" in warned


# -- 3. what the calibration says -------------------------------------------------------------------------


def _record(u, y):
    return sj.Record.from_arrays(np.arange(u.size) * DT, u, y, input_name="voltage_V", output_name="displacement_mm")


@pytest.mark.slow  # suite time (29 s on a busy machine; session 39 fresh-clone CI took 696 s)
def test_a_refinement_that_does_not_converge_is_said_once(truth, caplog):
    u = _drive()
    y = np.asarray(sj.simulate(sj.Recalibrated(truth, 1.08, 0.2, -0.15), u, DT))
    with caplog.at_level(logging.WARNING):
        _, info = sj.recalibrate(truth, u, y, DT, (0.0, 70.0), max_steps=3)
    assert info["converged"] is False and info["n_steps"] == 3
    text = next(w for w in info["warnings"] if "without converging" in w)
    assert "stopped after 3 steps (limit 3)" in text
    assert [r.getMessage() for r in caplog.records if "without converging" in r.getMessage()] == [text]
    # a converged one says nothing; log_warnings=False leaves the sentences to the caller
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        _, ok = sj.recalibrate(truth, u, y, DT, (0.0, 70.0))
        _, quiet = sj.recalibrate(truth, u, y, DT, (0.0, 70.0), max_steps=3, log_warnings=False)
    assert ok["converged"] and ok["warnings"] == [] and ok["segment_improved"]
    assert quiet["warnings"] and not caplog.records


def test_simulate_says_the_at_bound_warning_once(truth, caplog):
    u = _drive()
    # an input offset of 3 V: beyond the default bound (25 % of the 7.4 V span)
    y = np.asarray(sj.simulate(sj.Recalibrated(truth, 1.0, 3.0, 0.0), u, DT))
    with caplog.at_level(logging.WARNING):
        res = sj.simulate_record(truth, _record(u, y), measured="displacement_mm", calibrate=(0.0, 70.0))
    assert "input_offset" in res.calibration["at_bound"]
    said = [r.getMessage() for r in caplog.records if "ended at its bound" in r.getMessage()]
    assert len(said) == 1 and sum("ended at its bound" in w for w in res.warnings) == 1
    assert res.calibration["warnings"][0] == said[0]


@pytest.mark.slow  # suite time (session 71: 14 s under load); calibration recovery stays in test_recalibrate.py
def test_a_calibration_no_better_on_its_own_segment_is_said(truth):
    # the segment holds the input at 0 V: an input gain has nothing to act on there, so the fit cannot improve it
    u = np.r_[np.zeros(60), _drive(360)]
    y = np.asarray(sj.simulate(truth, u, DT)) + 0.1
    res = sj.simulate_record(truth, _record(u, y), measured="displacement_mm", calibrate=(0.0, 30.0), calibrate_fit="input_gain")
    cal = res.calibration
    assert cal["segment_rmse_after"] == pytest.approx(cal["segment_rmse_before"], rel=1e-12)
    assert cal["segment_improved"] is False
    w = next(w for w in res.warnings if w.startswith("calibration did not help on its own segment:"))
    assert "no better than the raw model" in w and f"'{res.output_name}_uncalibrated'" in w
    # both outputs are written: the re-anchored one as asked and the raw one beside it
    assert {res.output_name, f"{res.output_name}_uncalibrated"} <= set(res.columns)


def test_a_re_anchored_output_worse_after_the_segment_is_said(truth):
    u = _drive()
    raw = np.asarray(sj.simulate(truth, u, DT))
    y = raw.copy()
    y[:140] += 0.3  # the segment sits 0.3 above the model, the rest of the run does not
    res = sj.simulate_record(
        truth, _record(u, y), measured="displacement_mm", calibrate=(0.0, 70.0), calibrate_fit="output_offset"
    )
    s = res.scores
    assert s["recalibrated_after_segment"]["rmse"] > s["raw_after_segment"]["rmse"]
    w = next(w for w in res.warnings if w.startswith("calibration made the prediction worse after the segment"))
    raw_s, cal_s = s["raw_after_segment"], s["recalibrated_after_segment"]
    assert f"RMSE {raw_s['rmse']:.4g} (raw) -> {cal_s['rmse']:.4g} (re-anchored)" in w
    assert f"'{res.output_name}_uncalibrated'" in w
    # a calibration that helps after the segment: no such warning
    y_new = np.asarray(sj.simulate(sj.Recalibrated(truth, 1.0, 0.0, 0.25), u, DT))
    good = sj.simulate_record(
        truth, _record(u, y_new), measured="displacement_mm", calibrate=(0.0, 70.0), calibrate_fit="output_offset"
    )
    assert not any("worse after the segment" in w for w in good.warnings)
    after = after_segment_metrics(y_new, good.columns[f"{good.output_name}_uncalibrated"], good.y, 140)
    assert after["recalibrated"]["rmse"] < after["raw"]["rmse"]
