"""Re-anchoring a fitted model on a calibration segment of a new run (issue 14: deployment on a new run)."""

import csv
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.cli import main

DATASETS = Path(__file__).resolve().parents[1] / "datasets"
DT = 0.5


@pytest.fixture(scope="module")
def truth():
    return sj.load_model(DATASETS / "truth.json")


def _drive(n=420, top=7.4):
    """Triangular cycles of shrinking amplitude (major loop, then inner loops) starting at 0 V."""
    k = np.arange(n)
    period = 140
    phase = (k % period) / period
    amp = top * np.array([1.0, 0.75, 0.55])[np.minimum(k // period, 2)]
    return amp * (1.0 - np.abs(2.0 * phase - 1.0))


def _new_run(model, gain, offset, out_offset, n=420):
    """A "new run" of a known plant: the same model seen through a drifted input and a shifted output."""
    u = _drive(n)
    y = np.asarray(sj.simulate(sj.Recalibrated(model, gain, offset, out_offset), u, DT))
    return u, y


def test_recalibrated_is_the_wrapped_model_on_the_shifted_input(truth):
    u = _drive()
    r = sj.Recalibrated(truth, 1.1, -0.3, 0.25)
    direct = np.asarray(truth.simulate(jnp.asarray(1.1 * u - 0.3), DT)) + 0.25
    np.testing.assert_allclose(np.asarray(sj.simulate(r, u, DT)), direct, rtol=0, atol=1e-13)
    ident = sj.Recalibrated(truth)
    np.testing.assert_array_equal(np.asarray(sj.simulate(ident, u, DT)), np.asarray(sj.simulate(truth, u, DT)))


def test_recalibrate_recovers_gain_and_offsets_and_scores_after_the_segment(truth):
    gain, off, c = 1.08, 0.2, -0.15
    u, y = _new_run(truth, gain, off, c)
    fitted, info = sj.recalibrate(truth, u, y, DT, (0.0, 70.0))  # the first rising and falling curve (140 samples)
    assert info["input_gain"] == pytest.approx(gain, abs=1e-6)
    assert info["input_offset"] == pytest.approx(off, abs=1e-6)
    assert info["output_offset"] == pytest.approx(c, abs=1e-6)
    assert isinstance(fitted, sj.Recalibrated) and float(fitted.input_gain) == info["input_gain"]
    assert info["segment"] == {"start_s": 0.0, "end_s": 70.0, "start_sample": 0, "end_sample": 140, "n_samples": 140}
    assert info["scored_from_sample"] == 140 and info["scored_from_s"] == pytest.approx(70.0)
    assert info["segment_rmse_after"] < 1e-8 < 0.01 < info["segment_rmse_before"]

    from smafl_jax.identify import after_segment_metrics

    s = after_segment_metrics(y, sj.simulate(truth, u, DT), sj.simulate(fitted, u, DT), info["scored_from_sample"])
    assert s["raw"]["n_samples"] == s["recalibrated"]["n_samples"] == len(u) - 140
    assert s["recalibrated"]["rmse"] < 1e-8 and s["raw"]["rmse"] > 0.05
    assert s["recalibrated"]["e_r_percent"] < 1e-6


def test_output_offset_alone_is_the_mean_residual_over_the_segment(truth):
    u, y = _new_run(truth, 1.0, 0.0, 0.3)
    y = y + 0.01 * np.sin(np.arange(len(u)))  # a residual the offset cannot absorb
    fitted, info = sj.recalibrate(truth, u, y, DT, (10.0, 40.0), fit="output_offset")
    raw = np.asarray(sj.simulate(truth, u, DT))
    assert info["output_offset"] == pytest.approx(float(np.mean((y - raw)[20:80])), abs=1e-12)
    assert (info["input_gain"], info["input_offset"]) == (1.0, 0.0)
    assert info["segment"]["start_sample"] == 20 and info["segment"]["end_sample"] == 80
    assert info["method"].startswith("closed form")


def test_a_subset_keeps_the_others_and_a_second_calibration_starts_from_the_first(truth):
    u, y = _new_run(truth, 1.0, -0.25, 0.1)
    fitted, info = sj.recalibrate(truth, u, y, DT, slice(0, 140), fit=("input_offset", "output_offset"))
    assert info["input_gain"] == 1.0
    assert info["input_offset"] == pytest.approx(-0.25, abs=1e-6) and info["output_offset"] == pytest.approx(0.1, abs=1e-6)
    # re-anchoring an already re-anchored model: the kept parameters stay at its values, not at 1 / 0 / 0
    again, info2 = sj.recalibrate(fitted, u, y + 0.05, DT, slice(0, 140), fit="output_offset")
    assert isinstance(again.model, type(truth))
    assert info2["input_offset"] == pytest.approx(-0.25, abs=1e-6) and info2["output_offset"] == pytest.approx(0.15, abs=1e-6)


def test_input_parameters_stay_within_their_drift_bounds(truth):
    u, y = _new_run(truth, 1.08, 0.2, 0.0)
    _, info = sj.recalibrate(truth, u, y, DT, (0.0, 70.0), max_gain_ratio=1.02, max_input_offset=0.05)
    assert 1 / 1.02 <= info["input_gain"] <= 1.02 and abs(info["input_offset"]) <= 0.05
    assert info["at_bound"] == ["input_gain", "input_offset"]
    _, free = sj.recalibrate(truth, u, y, DT, (0.0, 70.0))
    assert free["at_bound"] == [] and free["bounds"]["input_offset"] == pytest.approx(0.25 * 7.4)
    with pytest.raises(sj.UserInputError, match="max_gain_ratio must be > 1"):
        sj.recalibrate(truth, u, y, DT, (0.0, 70.0), max_gain_ratio=0.9)


@pytest.mark.parametrize(
    ("segment", "fit", "match"),
    [
        ((30.0, 10.0), None, "the start must come before the end"),
        ((10.0, 10.0), None, "the start must come before the end"),
        ((-5.0, 10.0), None, "starts outside the record"),
        ((10.0, 500.0), None, "ends after the record"),
        ((10.1, 10.3), None, "holds no sample"),
        ((0.0, 5.0), None, "holds 10 sample.*needs at least 15"),
        ((0.0, 2.0), "output_offset", "holds 4 sample.*needs at least 5"),
        (slice(100, 500), None, "outside the record"),
        ((0.0, 30.0), ("input_gain", "scale"), "unknown parameter"),
        ((0.0, 30.0), (), "at least one"),
        ("0:30", None, "must be \\(start_s, end_s\\)"),
    ],
)
def test_bad_segments_and_names_raise_user_input_errors(truth, segment, fit, match):
    u, y = _new_run(truth, 1.0, 0.0, 0.0, n=200)  # 0 .. 99.5 s
    kwargs = {} if fit is None else {"fit": fit}
    with pytest.raises(sj.UserInputError, match=match):
        sj.recalibrate(truth, u, y, DT, segment, **kwargs)


def test_segment_times_count_from_the_record_start_time(truth):
    from smafl_jax.identify import segment_indices

    assert segment_indices((100.0, 110.0), 200, DT, t0=100.0) == (0, 20)
    assert segment_indices((None, 3.0), 200, DT, t0=0.0) == (0, 6)
    with pytest.raises(sj.UserInputError, match=r"starts outside the record, which runs from 100 s to 199\.5 s"):
        segment_indices((0.0, 10.0), 200, DT, t0=100.0)
    # a logger's first row at t = dt: `--calibrate 0:30` means from the record's start (up to one sample before it)
    assert segment_indices((0.0, 10.0), 200, DT, t0=DT) == (0, 19)  # 0.5 .. 9.5 s
    with pytest.raises(sj.UserInputError, match="starts outside the record"):
        segment_indices((0.0, 10.0), 200, DT, t0=2.5 * DT)


def test_save_and_load_round_trip(truth, tmp_path):
    r = sj.Recalibrated(truth, 1.05, 0.12, -0.07)
    sj.save_model(tmp_path / "recal.json", r)
    back = sj.load_model(tmp_path / "recal.json")
    assert isinstance(back, sj.Recalibrated) and type(back.model) is type(truth)
    assert back.calibration() == pytest.approx(r.calibration(), abs=0)
    u = _drive(200)
    np.testing.assert_array_equal(np.asarray(sj.simulate(back, u, DT)), np.asarray(sj.simulate(r, u, DT)))
    doc = json.loads((tmp_path / "recal.json").read_text())
    assert doc["model"]["type"] == "Recalibrated" and doc["model"]["model"]["type"] == "Cascade"
    bad = dict(doc["model"], input_gain=-1.0)
    with pytest.raises(sj.UserInputError, match="input_gain: must be >= 0"):
        sj.model_from_dict(bad)


def test_segment_loss_gradient_matches_finite_differences(truth):
    u, y = _new_run(truth, 1.05, 0.1, 0.0, n=140)
    uj, yj = jnp.asarray(u), jnp.asarray(y)

    def loss(p):
        r = sj.Recalibrated(truth, p[0], p[1], p[2])
        return 0.5 * jnp.sum((r.simulate(uj, DT)[20:] - yj[20:]) ** 2)

    p = jnp.asarray([1.0, 0.05, 0.02])
    g = np.asarray(jax.jit(jax.grad(loss))(p))
    loss = jax.jit(loss)
    h = 1e-6
    fd = [(float(loss(p.at[i].add(h))) - float(loss(p.at[i].add(-h)))) / (2 * h) for i in range(3)]
    np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-8)


def _write_record(path, u, y):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time_s", "voltage_V", "displacement_mm"])
        for k, (a, b) in enumerate(zip(u, y)):
            w.writerow([f"{k * DT:.3f}", repr(float(a)), repr(float(b))])


def test_cli_calibrate_writes_the_reanchored_output_and_scores_after_the_segment(truth, tmp_path, capsys):
    u, y = _new_run(truth, 1.06, 0.15, -0.1)
    data = tmp_path / "new_run.csv"
    _write_record(data, u, y)
    model = tmp_path / "model.json"
    sj.save_model(model, truth, data={"input_column": "voltage_V", "output_column": "displacement_mm", "input_range": [0.0, 7.4]})
    out, met = tmp_path / "sim.csv", tmp_path / "metrics.json"
    rc = main(["simulate", str(model), str(data), "--out", str(out), "--calibrate", "0:70", "--metrics", str(met)])
    assert rc == 0
    printed = capsys.readouterr().out
    assert "calibration on 0-70 s (140 samples" in printed and "input_gain 1.06" in printed
    doc = json.loads(met.read_text())
    assert doc["scored_from_s"] == pytest.approx(70.0) and doc["n_samples"] == len(u) - 140
    assert doc["rmse"] == doc["recalibrated_after_segment"]["rmse"] < 1e-6 < 0.05 < doc["raw_after_segment"]["rmse"]
    assert doc["calibration"]["input_offset"] == pytest.approx(0.15, abs=1e-6)
    with open(out) as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(u)
    sim = np.array([float(r["displacement_mm_model"]) for r in rows])
    np.testing.assert_allclose(sim, y, atol=1e-6)
    assert "displacement_mm_model_uncalibrated" in rows[0]

    # only the output offset: the gain and input offset stay put, and the printed line says so
    rc = main(["simulate", str(model), str(data), "--out", str(out), "--calibrate", ":70", "--calibrate-fit", "output_offset"])
    assert rc == 0
    assert "fitted: output_offset): input_gain 1," in capsys.readouterr().out


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--calibrate", "50:10"], "the start must come before the end"),
        (["--calibrate", "abc"], "expected START:END"),
        (["--calibrate", "0:70", "--calibrate-fit", "gain"], "unknown parameter"),
        (["--calibrate-fit", "output_offset"], "needs --calibrate"),
        (["--calibrate", "0:100", "--metrics", "M"], "nothing after it is left to score"),
    ],
)
def test_cli_calibrate_errors_write_nothing(truth, tmp_path, capsys, extra, match):
    u, y = _new_run(truth, 1.0, 0.0, 0.0, n=200)
    data = tmp_path / "new_run.csv"
    _write_record(data, u, y)
    model = tmp_path / "model.json"
    sj.save_model(model, truth, data={"input_column": "voltage_V", "output_column": "displacement_mm"})
    out = tmp_path / "sim.csv"
    extra = [str(tmp_path / "m.json") if a == "M" else a for a in extra]
    assert main(["simulate", str(model), str(data), "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err
    assert match in err.replace("\n", " "), err
    assert not out.exists() and not (tmp_path / "m.json").exists()
