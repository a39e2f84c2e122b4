"""Library workflows behind ``smafl control``, ``smafl sweep`` and ``smafl simulate``.

The library call and the command write the same files; the range warnings come back as data; bad
settings raise `UserInputError` before anything is written; and the CLI paths a user takes from a fit
(a Preisach fit driven by ``smafl control``, a cascade fit's k1).
"""

import dataclasses
import json
import logging
import os
from pathlib import Path

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.cli import main
from smafl_jax.workflows import control as WC
from smafl_jax.workflows import sweep as WS

DATASETS = Path(__file__).resolve().parents[1] / "datasets"
TRUTH = DATASETS / "truth.json"
TRUE_K1 = 0.0625  # datasets/README.md: the true cascade's k1 (1/s)

# a short, gentle loop: few samples, so each test compiles and runs in a couple of seconds
LOOP = {"kp": 0.5, "ki": 2.0, "K": 2.0, "duration": 3.0, "dt": 0.05}
LOOP_ARGS = ["--kp", "0.5", "--ki", "2", "--K", "2", "--duration", "3", "--dt", "0.05"]


@pytest.fixture(scope="module")
def narrow(tmp_path_factory):
    """The bundled true cascade saved as if fitted on 0-2 V drives: the loops below leave that range."""
    model = sj.load_model(TRUTH)
    x = np.asarray(model.hysteresis_input(np.linspace(0.0, 2.0, 400), 0.05))
    path = tmp_path_factory.mktemp("wfcli") / "narrow.json"
    data = {"input_column": "voltage_V", "output_column": "displacement_mm", "input_range": [0.0, 2.0]}
    sj.save_model(path, model, data={**data, "effective_input_range": [float(x.min()), float(x.max())]})
    return path


def _read_csv(path):
    return np.genfromtxt(path, delimiter=",", names=True)


def _json(path):
    return json.loads(Path(path).read_text())


def _short_record(path, source, n, step=1):
    d = _read_csv(DATASETS / source)[::step][:n]
    cols = {"time_s": d["time_s"] - d["time_s"][0], "voltage_V": d["voltage_V"], "displacement_mm": d["displacement_mm"]}
    sj.atomic_write_csv(path, cols)
    return path


# -- control ----------------------------------------------------------------------------------------------


def test_control_library_and_cli_write_the_same_results(narrow, tmp_path, capsys, caplog):
    cli, lib = tmp_path / "cli", tmp_path / "lib"
    assert main(["control", "--model", str(narrow), *LOOP_ARGS, "--noise", "0.01", "--seed", "3", "--out", str(cli)]) == 0
    printed = capsys.readouterr()
    with caplog.at_level(logging.INFO, logger="smafl_jax.workflows"):
        res = sj.run_control(narrow, out=lib, noise=0.01, seed=3, **LOOP)
    assert capsys.readouterr().out == ""  # the library prints nothing
    assert isinstance(res, sj.ControlResult) and res.out == lib
    assert sorted(os.listdir(cli)) == sorted(os.listdir(lib)) == sorted(WC.FILES) == sorted(res.files)
    assert (cli / "trajectory.csv").read_bytes() == (lib / "trajectory.csv").read_bytes()
    doc = _json(lib / "metrics.json")
    assert _json(cli / "metrics.json") == doc
    assert doc == json.loads(
        json.dumps(sj.to_jsonable({**res.metrics, "settings": res.settings, "range_checks": res.range_checks}))
    )
    # the returned trajectory is the written one, and the metrics are its extremes
    traj = _read_csv(lib / "trajectory.csv")
    np.testing.assert_allclose(traj["u"], res.trajectory["u"], rtol=1e-9, atol=1e-12)
    assert res.metrics["u_max_V"] == pytest.approx(traj["u"].max()) and res.settings["n_samples"] == traj.size == 60
    # the drive leaves the 0-2 V the plant was "fitted" on: a warning as data, logged, and shown by the command
    above = int(np.sum(res.trajectory["u"] > 2.0))
    assert above > 0 and res.range_checks[0]["n_above"] == above
    assert res.warnings and res.warnings[0].startswith("plant model: input 'drive u' leaves the range the model was fitted on")
    assert f"warning: {res.warnings[0]}" in printed.err
    assert "simulating 60 samples (composite)" in caplog.text and res.warnings[0] in caplog.text
    assert f"e_mean {res.metrics['e_mean_mm']:.4g} mm" in printed.out and printed.out.strip().endswith(str(cli))


# -- sweep ------------------------------------------------------------------------------------------------


def test_sweep_of_a_slow_thermal_mode(tmp_path):
    # a plant with a slow thermal mode: each cell of a sweep over its rate and share is the single run with those values
    m = sj.load_model(TRUTH)
    slow = dataclasses.replace(m, thermal=m.thermal.with_slow_mode(0.02, 0.5))
    res = sj.run_sweep("slow_k1=0.005,0.05", ("slow_ratio", [0.2, 1.0]), slow, out=tmp_path, progress=False, **LOOP)
    e = res.metrics["e_mean_mm"]
    assert e.shape == (2, 2) and np.ptp(e) > 0  # the slow mass changes what the loop tracks
    plant = dataclasses.replace(m, thermal=m.thermal.with_slow_mode(0.05, 0.2))
    loop, _ = WC.build_loop(plant, **LOOP)
    assert float(sj.closed_loop_metrics(loop, LOOP["dt"])["e_mean_mm"]) == pytest.approx(e[1, 0], rel=1e-9)


def test_sweep_library_and_cli_write_the_same_results(narrow, tmp_path, capsys):
    cli, lib = tmp_path / "cli", tmp_path / "lib"
    argv = ["sweep", "--model", str(narrow), *LOOP_ARGS, "--x", "kp=0.2,1", "--y", "K=0:2:2", "--top", "3", "--out", str(cli)]
    assert main(argv) == 0
    printed = capsys.readouterr()
    res = sj.run_sweep("kp=0.2,1", ("K", [0.0, 2.0]), narrow, out=lib, top=3, progress=False, **LOOP)
    assert capsys.readouterr().out == ""
    assert isinstance(res, sj.ControlSweepResult)
    assert sorted(os.listdir(cli)) == sorted(os.listdir(lib)) == sorted(WS.FILES)
    for name in ("sweep.csv", "best.csv"):
        assert (cli / name).read_bytes() == (lib / name).read_bytes(), name
    assert _json(cli / "metrics.json") == _json(lib / "metrics.json")
    # the grid: x-major, best first, each cell the single run of its settings
    e = res.metrics["e_mean_mm"]
    assert e.shape == (2, 2) and list(res.axes) == ["kp", "K"]
    assert list(res.order) == list(np.argsort(e.ravel())[:3]) and res.best["e_mean_mm"] == e.min()
    loop, _ = WC.build_loop(narrow, **{**LOOP, "kp": 1.0, "K": 0.0})
    single = sj.closed_loop_metrics(loop, LOOP["dt"])
    assert float(single["e_mean_mm"]) == pytest.approx(e[1, 0], rel=1e-9)
    rows = _read_csv(lib / "sweep.csv")
    assert (rows["kp"][2], rows["K"][2]) == (1.0, 0.0) and rows["e_mean_mm"][2] == pytest.approx(e[1, 0], rel=1e-9)
    # configurations outside the fitted drive range: counted, warned about (as data and on stderr)
    n_out = int(np.sum(rows["u_max_V"] > 2.0 + res.range_check["tolerance"]))
    assert n_out > 0 and res.range_check["n_outside"] == n_out and res.warnings == [res.range_check["warning"]]
    assert f"warning: {res.warnings[0]}" in printed.err and "sweep: 4/4 configurations" in printed.err
    assert f"{res.best['e_mean_mm']:>12.4g}" in printed.out.splitlines()[1]


# -- simulate ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("calibrate", [None, "0:100"])
def test_simulate_library_and_cli_write_the_same_results(narrow, tmp_path, capsys, calibrate):
    data = DATASETS / "minor_loop.csv"
    extra = ["--calibrate", calibrate] if calibrate else []
    argv = ["simulate", str(narrow), str(data), "--out", str(tmp_path / "cli.csv"), "--metrics", str(tmp_path / "cli.json")]
    assert main([*argv, *extra]) == 0
    printed = capsys.readouterr()
    res = sj.simulate_record(narrow, data, out=tmp_path / "lib.csv", metrics_file=tmp_path / "lib.json", calibrate=calibrate)
    assert capsys.readouterr().out == ""
    assert isinstance(res, sj.SimulationResult) and res.out == tmp_path / "lib.csv"
    assert (tmp_path / "cli.csv").read_bytes() == (tmp_path / "lib.csv").read_bytes()
    doc = _json(tmp_path / "lib.json")
    assert _json(tmp_path / "cli.json") == doc
    assert doc["rmse"] == pytest.approx(res.scores["rmse"]) and doc["measured_column"] == res.measured == "displacement_mm"
    assert f"wrote {tmp_path / 'cli.csv'} ({len(res.record)} samples, column 'displacement_mm_model')" in printed.out
    # the input leaves the 0-2 V of the "fit": the warnings come back as data and the command shows them
    assert res.warnings and all(f"warning: {w}" in printed.err for w in res.warnings)
    assert doc["input_range_check"] == json.loads(json.dumps(res.range_checks[0]))
    rec = sj.load_record(data)
    if calibrate is None:
        y = np.asarray(sj.simulate(sj.load_model(narrow), rec.u, rec.dt))
        np.testing.assert_allclose(res.y, y, rtol=1e-12, atol=1e-12)
        assert res.scores["rmse"] == pytest.approx(np.sqrt(np.mean((rec.y - y) ** 2)), rel=1e-9)
    else:
        k = res.calibration["scored_from_sample"]
        assert res.calibration["segment"]["start_s"] == 0.0 and k == int(round(100 / rec.dt))
        assert doc["n_samples"] == len(rec) - k and "displacement_mm_model_uncalibrated" in res.columns
        assert f"calibration on 0-100 s ({k} samples" in printed.out
        assert res.scores["rmse"] == pytest.approx(np.sqrt(np.mean((rec.y[k:] - res.y[k:]) ** 2)), rel=1e-9)


def test_simulate_takes_python_objects_and_writes_only_what_is_asked(narrow, tmp_path):
    data = DATASETS / "minor_loop.csv"
    by_path = sj.simulate_record(narrow, data)
    rec = sj.load_record(data)  # the measured column is the record's output here, not an extra column
    res = sj.simulate_record(sj.load_model(narrow), rec, measured="displacement_mm")
    assert res.out is None and res.metrics_file is None
    np.testing.assert_array_equal(res.y, by_path.y)
    assert res.scores["rmse"] == pytest.approx(by_path.scores["rmse"], rel=1e-12)
    assert res.output_name == "output_model"  # a model object carries no fit.json column names
    # without the fitted ranges of a fit.json, nothing is warned about; the check says it was not made
    assert not res.warnings and not res.range_checks[0]["checked"]


# -- bad settings -----------------------------------------------------------------------------------------


def _call(kind, tmp_path, narrow, kw):
    kw = dict(kw)
    if kind == "control":
        return sj.run_control(kw.pop("model", TRUTH), out=tmp_path / "out", **{**LOOP, **kw})
    if kind == "sweep":
        x, y = kw.pop("x", "kp=1,2"), kw.pop("y", "ki=1,2")
        return sj.run_sweep(x, y, kw.pop("model", TRUTH), out=tmp_path / "out", progress=False, **{**LOOP, **kw})
    data = kw.pop("data", DATASETS / "minor_loop.csv")
    return sj.simulate_record(narrow, data, out=tmp_path / "out.csv", metrics_file=tmp_path / "m.json", **kw)


@pytest.mark.parametrize(
    ("kind", "kw", "match"),
    [
        ("control", {"kp": -1.0}, r"kp must be >= 0, got -1.0"),
        ("control", {"dt": 0.0}, r"dt must be > 0"),
        ("control", {"controller": "pi"}, r"controller must be one of"),
        ("control", {"reference": "no_such_reference.csv"}, r"not 'sine' or 'step' and no such file"),
        ("control", {"duration": 1e9}, r"more than the limit"),
        ("control", {"model": "no_such_model.json"}, r"no_such_model.json"),
        ("sweep", {"x": "kp=-1,2"}, r"sweep axis 'kp=-1,2': kp must be >= 0"),
        ("sweep", {"x": ("tf", [0.0, 1.0])}, r"tf must be > 0"),
        ("sweep", {"x": "ki=1,2"}, r"x and y both sweep 'ki'"),
        ("sweep", {"x": "K=0,1", "controller": "pid"}, r"sweeping K needs controller composite"),
        ("sweep", {"top": 0}, r"top must be >= 1"),
        ("sweep", {"x": "gain=1,2"}, r"choose one of"),
        ("sweep", {"x": "k1=0.05", "model": "HYSTERESIS"}, r"needs a plant with a thermal part"),
        ("sweep", {"x": "slow_k1=0.01"}, r"sweeping slow_k1 needs a plant with a slow thermal mode"),
        ("sweep", {"x": "slow_ratio=0,1"}, r"slow_ratio values must be > 0, got 0"),
        ("simulate", {"calibrate_fit": "output_offset"}, r"calibrate_fit needs calibrate"),
        ("simulate", {"calibrate": "abc"}, r"expected START:END"),
        ("simulate", {"calibrate": "0:70", "calibrate_fit": "gain"}, r"unknown parameter"),
        ("simulate", {"calibrate": "0:1000"}, r"ends after the record"),
        ("simulate", {"initial_state": "warm"}, r"initial_state must be one of"),
        ("simulate", {"measured": "nope"}, r"no column 'nope' to score against"),
        ("simulate", {"output_name": "voltage_V"}, r"clashes with an input column"),
        ("simulate", {"data": "NO_OUTPUT"}, r"metrics_file needs a measured output column"),
    ],
)
def test_bad_settings_raise_before_anything_is_written(narrow, tmp_path, kind, kw, match):
    kw = dict(kw)
    if kw.get("model") == "HYSTERESIS":
        kw["model"] = sj.load_model(TRUTH).hysteresis  # a model object without a thermal part
    if kw.get("data") == "NO_OUTPUT":
        d = _read_csv(DATASETS / "minor_loop.csv")[:50]
        kw["data"] = tmp_path / "input_only.csv"
        sj.atomic_write_csv(kw["data"], {"time_s": d["time_s"], "voltage_V": d["voltage_V"]})
    with pytest.raises(sj.UserInputError, match=match):
        _call(kind, tmp_path, narrow, kw)
    assert not (tmp_path / "out").exists() and not (tmp_path / "out.csv").exists() and not (tmp_path / "m.json").exists()


def test_cli_errors_name_the_flags(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["sweep", "--model", str(TRUTH), "--x", "ki=1,2", "--y", "ki=3,4", "--out", str(out)]) == 2
    assert "smafl sweep: error: --x and --y both sweep 'ki'" in capsys.readouterr().err
    assert main(["sweep", "--model", str(TRUTH), "--x", "kp=1,2", "--y", "ki=3,4", "--top", "0", "--out", str(out)]) == 2
    assert "--top must be >= 1, got 0" in capsys.readouterr().err
    assert main(["control", "--model", str(TRUTH), "--eval-start", "-1", "--out", str(out)]) == 2
    assert "smafl control: error: --eval-start must be >= 0" in capsys.readouterr().err
    assert not out.exists()


# -- the user's path from a fit ---------------------------------------------------------------------------


@pytest.mark.slow  # ~12 s; test_hysteresis_protocol.py runs the same fit -> control path (and sweep, sample) by default
def test_cli_fit_preisach_then_control(tmp_path, capsys):
    record = _short_record(tmp_path / "rec.csv", "main_loop.csv", 400)
    fit_dir = tmp_path / "fit"
    assert main(["fit", str(record), "--model", "preisach", "--max-steps", "0", "--no-figures", "--out", str(fit_dir)]) == 0
    doc = _json(fit_dir / "fit.json")
    assert doc["model"]["type"] == "Preisach" and len(doc["data"]["input_range"]) == 2
    assert main(["control", "--model", str(fit_dir / "fit.json"), *LOOP_ARGS, "--out", str(tmp_path / "c")]) == 0
    metrics = _json(tmp_path / "c" / "metrics.json")
    assert np.isfinite(metrics["e_mean_mm"]) and metrics["settings"]["compensator_forward_model"] == "static Preisach"
    assert metrics["settings"]["plant_fitted_ranges"]["input_range"] == doc["data"]["input_range"]
    traj = _read_csv(tmp_path / "c" / "trajectory.csv")
    assert np.all(np.isfinite(traj["y"])) and traj["u"].min() >= 0.0 and traj["u"].max() <= 7.4
    assert metrics["range_checks"][0]["checked"]  # the fit's training range is known, so the drive is checked


@pytest.mark.slow  # suite time (10-minute budget): 18 s; cascade k1 recovery is tested through the library in test_fit.py
def test_cli_cascade_fit_recovers_a_finite_positive_k1(tmp_path, capsys):
    # the step record shows the thermal lag; every other sample of its first 1000 s keeps the test short
    record = _short_record(tmp_path / "steps.csv", "steps.csv", 500, step=2)
    argv = ["fit", str(record), "--model", "cascade", "--orientation", "rises", "--sees", "voltage", "--max-steps", "0"]
    assert main([*argv, "--no-figures", "--out", str(tmp_path / "fit")]) == 0
    k1 = _json(tmp_path / "fit" / "fit.json")["model"]["thermal"]["k1"]
    assert isinstance(k1, float) and np.isfinite(k1) and k1 > 0
    assert k1 == pytest.approx(TRUE_K1, rel=0.2)  # the bundled records' true thermal rate (datasets/README.md)
