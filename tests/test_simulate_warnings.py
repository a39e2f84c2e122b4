"""What `smafl simulate` says about a new record: range exits beyond a tolerance, blank measured cells left out of the
score, which start a record that is not a training record gets, and a measured column in other units."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.cli import main
from smafl_jax.models import range_check
from smafl_jax.models._range import OUTPUT_TOL, RANGE_TOL, output_check  # private: white-box tests of the tolerances
from smafl_jax.workflows.simulate import fitted_output_span

DATASETS = Path(__file__).resolve().parents[1] / "datasets"
DT = 0.05


def _drive(n=600, amp=1.0, seed=0):
    """A slow drive between 0.5 and 3.5 V (times ``amp`` around 2 V)."""
    t = np.arange(n) * DT
    rng = np.random.default_rng(seed)
    return 2.0 + amp * (1.5 * np.sin(2 * np.pi * t / 12.0 + rng.uniform(0, 6)) * np.sin(2 * np.pi * t / 31.0 + 1.0))


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    """The bundled true cascade saved with the ranges of the drive it is run on below (as if fitted on it)."""
    tmp = tmp_path_factory.mktemp("simwarn")
    model = sj.load_model(DATASETS / "truth.json")
    u = _drive()
    y = np.asarray(sj.simulate(model, u, DT)) + np.random.default_rng(1).normal(0.0, 0.002, u.size)
    x = np.asarray(model.hysteresis_input(u, DT))
    csv = tmp / "rec.csv"
    sj.atomic_write_csv(csv, {"time_s": np.arange(u.size) * DT, "voltage_V": u, "displacement_mm": y})
    span_x = float(np.ptp(x))
    data = {
        "input_column": "voltage_V",
        "output_column": "displacement_mm",
        "sample_time_s": DT,
        # a hair inside the record's own range (a print precision, a start a few mV cooler): strict exits, no warning
        "input_range": [float(u.min()) + 1e-6, float(u.max())],
        "effective_input_range": [float(x.min()) + 1e-4 * span_x, float(x.max())],
        "output_range": [float(y.min()), float(y.max())],
        "sha256": "0" * 64,  # not this record
    }
    path = tmp / "model.json"
    sj.save_model(path, model, data=data)
    return {"tmp": tmp, "model": model, "path": path, "csv": csv, "u": u, "y": y, "data": data}


def test_range_check_tolerates_tiny_exits_and_warns_real_ones_with_their_size():
    u = np.linspace(0.0, 4.0, 401)
    tiny = range_check(np.r_[u, 4.0 + 0.5 * RANGE_TOL * 4.0], [0.0, 4.0], dt=0.1)
    assert (tiny["n_above"], tiny["n_beyond_tolerance"], tiny["n_within_tolerance"]) == (1, 0, 1)
    assert tiny["max_above"] == pytest.approx(0.5 * RANGE_TOL * 4.0) and "warning" not in tiny
    assert tiny["tolerance"] == {"fraction_of_span": RANGE_TOL, "value": pytest.approx(RANGE_TOL * 4.0)}
    real = range_check(np.r_[u, 4.5, 4.5, -1e-6], [0.0, 4.0], "v", dt=0.1)
    assert (real["n_above"], real["n_below"], real["n_beyond_tolerance"], real["n_exits"]) == (2, 1, 2, 1)
    w = real["warning"]
    assert "2 of 404 samples" in w and "2 above the max by up to 0.5 (12.5 % of the fitted span)" in w
    assert "below the min" not in w  # the 1e-6 exit is counted above, not warned about
    assert real["exits"] == [
        {"start_sample": 401, "end_sample": 403, "start_s": pytest.approx(40.1), "duration_s": pytest.approx(0.2)}
    ]
    assert RANGE_TOL <= 0.02  # at most the branch check's deadband: a real exit of a few % still warns


def test_simulate_does_not_warn_a_hair_outside_but_counts_it(setup, tmp_path):
    mfile = tmp_path / "m.json"
    res = sj.simulate_record(setup["path"], setup["csv"], metrics_file=mfile)
    assert not any("leaves the range" in w for w in res.warnings)
    doc = json.loads(mfile.read_text())
    raw, eff = doc["input_range_check"], doc["effective_input_range_check"]
    assert raw["n_below"] >= 1 and raw["n_beyond_tolerance"] == 0 and raw["tolerance"]["fraction_of_span"] == RANGE_TOL
    assert eff["n_below"] >= 1 and eff["max_below"] > 0 and "warning" not in eff
    # the same model on a drive 0.6 V above its trained maximum: warned, with the size
    u = setup["u"].copy()
    u[200:260] = u.max() + 0.6
    csv = tmp_path / "over.csv"
    sj.atomic_write_csv(csv, {"time_s": np.arange(u.size) * DT, "voltage_V": u})
    res = sj.simulate_record(setup["path"], csv)
    w = next(w for w in res.warnings if w.startswith("input 'voltage_V' leaves the range"))
    assert "60 above the max by up to 0.6" in w and "first at 10 s for 3 s" in w


def test_output_check_warns_only_when_the_input_stays_in_range():
    y = np.r_[np.linspace(0.0, 1.0, 50), 1.0 + 1.5 * OUTPUT_TOL, 0.5]
    c = output_check(y, [0.0, 1.0], input_inside=True, dt=0.1)
    assert c["n_beyond_tolerance"] == 1 and c["max_outside"] == pytest.approx(1.5 * OUTPUT_TOL)
    assert "leaves the range of the output it was fitted on" in c["warning"] and "first at 5 s" in c["warning"]
    # the input leaves its own range too: said, not warned
    c = output_check(y, [0.0, 1.0], input_inside=False, dt=0.1)
    assert "warning" not in c and "input leaves its trained range too" in c["note"]
    # within the tolerance, or no range in the file
    assert "warning" not in output_check(np.r_[y[:50], 1.0 + 0.5 * OUTPUT_TOL], [0.0, 1.0], input_inside=True)
    assert not output_check(y, None, input_inside=True)["checked"]


def test_simulate_warns_when_the_model_output_leaves_its_fitted_range(setup, tmp_path):
    """An output far beyond what the model was fitted to reach, with the input in range, is an extrapolation on an
    untrained branch: independent plants' own outputs stayed within 6 % of the span there."""
    mfile = tmp_path / "m.json"
    res = sj.simulate_record(setup["path"], setup["csv"], metrics_file=mfile)
    assert not any("output it was fitted on" in w for w in res.warnings)
    assert json.loads(mfile.read_text())["output_range_check"]["n_beyond_tolerance"] == 0
    y = setup["y"]
    narrow = tmp_path / "narrow.json"  # as if the fitted record's output had spanned only its lower half
    lo, hi = float(y.min()), float(y.min() + 0.5 * np.ptp(y))
    sj.save_model(narrow, setup["model"], data={**setup["data"], "output_range": [lo, hi]})
    w = next(w for w in sj.simulate_record(narrow, setup["csv"]).warnings if "output it was fitted on" in w)
    assert "while its input stays inside the trained range" in w


def test_blank_measured_cells_are_left_out_of_the_score_and_kept_in_the_csv(setup, tmp_path):
    rec = sj.load_record(setup["csv"])
    y = np.array(rec.y)
    gap = [0, 100, 101, 102, 450]
    y[gap] = np.nan
    holed = dataclasses.replace(rec, y=y)
    out, mfile = tmp_path / "out.csv", tmp_path / "m.json"
    res = sj.simulate_record(setup["path"], holed, out=out, metrics_file=mfile)
    ok = np.isfinite(y)
    err = y[ok] - res.y[ok]
    s = res.scores
    assert s["n_left_out"] == len(gap) and s["n_samples"] == ok.sum()
    assert s["rmse"] == pytest.approx(np.sqrt(np.mean(err**2)), rel=1e-12)
    assert s["e_r_percent"] == pytest.approx(np.max(np.abs(err)) / np.ptp(y[ok]) * 100, rel=1e-12)
    assert np.isfinite(s["noise"]["sd"]) and np.isfinite(s["noise"]["scored_ratio"])
    # the noise scale of the holed record matches the full one's (second differences never straddle a blank cell)
    full = sj.simulate_record(setup["path"], rec).scores
    assert s["noise"]["sd"] == pytest.approx(full["noise"]["sd"], rel=0.1)
    assert any(f"{len(gap)} blank/NaN sample(s) left out of the score" in n for n in res.notes)
    written = np.genfromtxt(out, delimiter=",", names=True)
    assert np.array_equal(np.flatnonzero(np.isnan(written["displacement_mm"])), gap)
    assert json.loads(mfile.read_text())["n_left_out"] == len(gap)
    # the start estimate bridges the blank cells instead of failing on them
    est = sj.simulate_record(setup["path"], holed, initial_state="estimate")
    assert est.scores["n_left_out"] == len(gap) and any("bridged by linear interpolation" in n for n in est.notes)


def test_a_new_record_is_told_which_start_it_gets(setup, tmp_path, capsys):
    model = setup["model"]
    u0 = float(model.thermal.start_voltage(float(setup["u"][0])))
    res = sj.simulate_record(setup["path"], setup["csv"])
    note = next(n for n in res.notes if "is not a training record" in n)
    assert f"({u0:.3g} V)" in note and "operator memory descended" in note and "estimate" in note
    argv = ["simulate", str(setup["path"]), str(setup["csv"]), "--out", str(tmp_path / "o.csv")]
    assert main(argv) == 0
    assert "use --initial-state estimate" in capsys.readouterr().err
    # the fitted record itself (same content): no such note
    own = setup["tmp"] / "own.json"
    sj.save_model(own, model, data={**setup["data"], "sha256": sj.load_record(setup["csv"]).sha256})
    assert not any("training record" in n for n in sj.simulate_record(own, setup["csv"]).notes)
    # the estimate says the start in volts, not as a bare fraction
    est = next(n for n in sj.simulate_record(setup["path"], setup["csv"], initial_state="estimate").notes if "initial state" in n)
    assert est.startswith("initial state estimate: thermal state at t=0 ") and " V" in est and "thermal 0." not in est
    # ... and what it compared: an estimate that keeps the start as fitted is not mistaken for one that did nothing
    assert "(the best of 24 starts, thermal state x operator memory, on the first " in est and "the start as fitted " in est


def test_a_measured_column_in_other_units_is_warned(setup, tmp_path):
    u, y = setup["u"], setup["y"]
    csv = tmp_path / "metres.csv"
    sj.atomic_write_csv(csv, {"time_s": np.arange(u.size) * DT, "voltage_V": u, "displacement_mm": y / 1000.0})
    res = sj.simulate_record(setup["path"], csv)
    w = next(w for w in res.warnings if w.startswith("possible unit mismatch"))
    assert "'displacement_mm'" in w
    assert res.scores["output_scale_check"]["ratios"]["fitted"] == pytest.approx(1e-3, rel=1e-9)
    assert not any("unit" in w for w in sj.simulate_record(setup["path"], setup["csv"]).warnings)
    # a small drive moves the output far less than the fitted range, and so does the model: not a unit problem
    small = _drive(amp=0.05)
    ys = np.asarray(sj.simulate(setup["model"], small, DT))
    csv2 = tmp_path / "small.csv"
    sj.atomic_write_csv(csv2, {"time_s": np.arange(small.size) * DT, "voltage_V": small, "displacement_mm": ys})
    res = sj.simulate_record(setup["path"], csv2)
    assert res.scores["output_scale_check"]["ratios"]["fitted"] < 0.1 and not any("unit" in w for w in res.warnings)
    # a fit.json without data.output_range: the range comes back from the metrics (eq. 3: e_r = max|error| / range)
    doc = {"metrics": {"whole_record": {"e_r_percent": 2.0, "max_abs_error": 0.08}}}
    assert fitted_output_span(doc) == pytest.approx(4.0) and fitted_output_span({}) is None


def test_a_measured_column_read_the_other_way_is_warned_and_can_be_flipped(setup, tmp_path, capsys):
    """A sensor read as ``c - y`` (trial 5: 1.6e4x the noise, no hint): simulate names it and ``--measured-sign -1``
    scores against the flipped column (the CSV keeps it as read); calibrating on it warns too."""
    u, y = setup["u"], setup["y"]
    csv = tmp_path / "reversed.csv"
    sj.atomic_write_csv(csv, {"time_s": np.arange(u.size) * DT, "voltage_V": u, "displacement_mm": 85.0 - y})
    res = sj.simulate_record(setup["path"], csv)
    w = next(w for w in res.warnings if "runs against the model's output" in w)
    assert "'displacement_mm'" in w and "-1" in w
    check = res.scores["output_sign_check"]
    assert check["correlation"] < -0.99 and check["rmse_flipped_offset_removed"] < 0.1 * check["rmse_offset_removed"]
    # the column as read, and its own record: no warning
    assert not any("runs against" in w for w in sj.simulate_record(setup["path"], setup["csv"]).warnings)
    # flipped as asked: scored against -(85 - y) = y - 85, so only the offset is left; the CSV keeps the column as read
    out = tmp_path / "sim.csv"
    assert main(["simulate", str(setup["path"]), str(csv), "--out", str(out), "--measured-sign", "-1", "--metrics",
                 str(tmp_path / "m.json")]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert "runs against" not in err and "sign flipped" in err
    m = json.loads((tmp_path / "m.json").read_text())
    assert m["output_sign_check"]["correlation"] > 0.99
    assert m["rmse"] == pytest.approx(85.0, rel=0.01)
    import csv as csvmod

    with out.open() as f:
        rows = list(csvmod.DictReader(f))
    assert float(rows[0]["displacement_mm"]) == pytest.approx(85.0 - y[0], rel=1e-9)
    # with a calibration on the reversed column: warned as well (the calibration cannot flip it)
    res = sj.simulate_record(setup["path"], csv, calibrate="0:10")
    assert any("runs against the model's output" in w for w in res.warnings)
    res = sj.simulate_record(setup["path"], csv, calibrate="0:10", measured_sign=-1)
    assert not any("runs against" in w for w in res.warnings)
    with pytest.raises(sj.UserInputError, match="measured_sign must be 1 or -1"):
        sj.simulate_record(setup["path"], csv, measured_sign=2)


def test_a_drive_below_its_range_with_the_thermal_state_inside_is_a_note_not_a_warning(setup, tmp_path):
    """Short 0 V off phases (a PWM run) leave the raw drive's fitted range, but the thermal lag keeps what the hysteresis
    sees inside its trained range: said as a note, and the raw check still counts every sample."""
    u = setup["u"].copy()
    k = int(np.argmax(u))
    u[k : k + 6] = 0.0  # 0.3 s off at the hottest point; the thermal time constant is 16 s
    csv = tmp_path / "pwm_dip.csv"
    sj.atomic_write_csv(csv, {"time_s": np.arange(u.size) * DT, "voltage_V": u})
    res = sj.simulate_record(setup["path"], csv)
    raw, eff = res.range_checks[0], res.range_checks[1]
    assert raw["n_beyond_tolerance"] == 6 and "warning" not in raw and "warning" not in eff
    assert "stays inside its trained range" in raw["note"] and "6 below the min" in raw["note"]
    assert not any("leaves the range" in w for w in res.warnings)
    assert any("stays inside its trained range" in n for n in res.notes)
    # held off long enough for the thermal state to leave its range too: both are warnings again
    u = np.r_[u, np.zeros(1200)]  # 60 s off: the actuator cools below anything its training saw
    sj.atomic_write_csv(csv, {"time_s": np.arange(u.size) * DT, "voltage_V": u})
    res = sj.simulate_record(setup["path"], csv)
    assert "warning" in res.range_checks[0] and "warning" in res.range_checks[1]


def test_an_output_read_from_another_zero_is_named_as_an_offset(setup, tmp_path):
    """A measured column shifted by a constant (a re-zeroed sensor): the warning names the offset and the
    calibration that removes it; a model off by its noise alone, or by a shape error, gets none."""
    from smafl_jax.workflows.simulate import output_offset_check

    rec = sj.load_record(setup["csv"])
    shifted = tmp_path / "rezeroed.csv"
    sj.atomic_write_csv(shifted, {"time_s": rec.time, "voltage_V": rec.u, "displacement_mm": rec.y - 0.3})
    res = sj.simulate_record(setup["path"], shifted)
    w = next(w for w in res.warnings if w.startswith("the error is mostly one constant offset"))
    assert "reads -0.3" in w and "calibrate START:END calibrate_fit output_offset" in w
    chk = res.scores["output_offset_check"]
    assert chk["mean_error"] == pytest.approx(-0.3, abs=0.002) and chk["share_of_mse"] > 0.99
    assert not any("constant offset" in w for w in sj.simulate_record(setup["path"], setup["csv"]).warnings)
    t = np.linspace(0.0, 1.0, 500)
    assert "warning" not in output_offset_check(np.sin(9 * t), np.sin(9 * t) * 0.5, 0.01, "y")  # a shape error
    assert "warning" not in output_offset_check(t + 0.02, t, 0.01, "y")  # 2 noise SDs: too small to name
    assert "warning" in output_offset_check(t + 0.06, t, 0.01, "y")
    assert output_offset_check(t, t, None, "y") == {"rule": chk["rule"], "checked": False}
