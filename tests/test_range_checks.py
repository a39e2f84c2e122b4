"""Trained-range checks (issue 18): fit stores raw and effective ranges; simulate, control and sweep warn."""

import json
from pathlib import Path

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.cli import main
from smafl_jax.models import range_check

DATASETS = Path(__file__).resolve().parents[1] / "datasets"


def test_range_check_reports_each_stretch_with_time_and_size():
    dt = 0.1
    u = np.zeros(100)
    u[10:15] = 5.0  # 0.5 s above, 1 V over
    u[40:60] = 4.5  # 2 s above, longest
    u[80] = -1.0  # one sample below
    c = range_check(u, [0.0, 4.0], "v", dt=dt)
    assert (c["n_above"], c["n_below"], c["n_exits"]) == (25, 1, 3)
    assert [(e["start_sample"], e["end_sample"]) for e in c["exits"]] == [(10, 15), (40, 60), (80, 81)]
    assert c["exits"][1]["start_s"] == pytest.approx(4.0) and c["exits"][1]["duration_s"] == pytest.approx(2.0)
    assert c["max_above"] == pytest.approx(1.0) and c["max_below"] == pytest.approx(1.0)
    # the warning names when (the longest stretch and the first exit on each side) and how far
    w = c["warning"]
    assert "the longest at 4 s for 2 s" in w and "first at 1 s for 0.5 s" in w and "25.0 % of the fitted span" in w
    assert "warning" not in range_check(u, [-1.0, 5.0], dt=dt)
    assert not range_check(u, None)["checked"]


def test_fit_stores_effective_range_of_the_saved_model(tmp_path):
    from smafl_jax.report import fit_record

    rec = sj.load_record(DATASETS / "main_loop.csv")
    # one start candidate (the screening itself is tested in test_auto_fit): this test is about the stored ranges
    model, doc, (train, _, _) = fit_record(
        rec, model="cascade", max_steps=0, refit=False, orientation="rises", sees="voltage", thermal_start="steady",
        memory="descended",
    )  # fmt: skip
    x = np.asarray(model.hysteresis_input(rec.u, rec.dt))
    assert doc["data"]["effective_input_range"] == pytest.approx([x[train].min(), x[train].max()], rel=1e-12)
    assert doc["data"]["input_range"] == pytest.approx([rec.u[train].min(), rec.u[train].max()], rel=1e-12)
    assert doc["data"]["output_range"] == pytest.approx([rec.y[train].min(), rec.y[train].max()], rel=1e-12)


def test_fit_stores_the_range_of_the_refitted_model():
    """After the whole-record refit the saved model has seen every sample: its stored ranges are the whole record's
    (they were the split's training part, so `smafl simulate` warned about drives the saved model was fitted on)."""
    from smafl_jax.report import fit_record

    rec = sj.load_record(DATASETS / "main_loop.csv")
    model, doc, (train, val, _) = fit_record(
        rec, model="cascade", max_steps=0, orientation="rises", sees="voltage", thermal_start="steady", memory="descended",
    )  # fmt: skip
    assert doc["split_model"] is not None and val.any()
    x = np.asarray(model.hysteresis_input(rec.u, rec.dt))
    assert doc["data"]["effective_input_range"] == pytest.approx([x.min(), x.max()], rel=1e-12)
    assert doc["data"]["input_range"] == pytest.approx([rec.u.min(), rec.u.max()], rel=1e-12)
    assert doc["data"]["output_range"] == pytest.approx([rec.y.min(), rec.y.max()], rel=1e-12)
    # the record's validation block reaches inputs its training part does not: the two ranges differ
    assert rec.u.max() > rec.u[train].max() or rec.u.min() < rec.u[train].min() or x.max() > x[train].max()


@pytest.fixture
def narrow_model(tmp_path):
    """The bundled truth cascade, saved as if it had been fitted on drives of 0-2 V only."""
    model = sj.load_model(DATASETS / "truth.json")
    x = np.asarray(model.hysteresis_input(np.linspace(0.0, 2.0, 400), 0.05))
    path = tmp_path / "narrow.json"
    sj.save_model(path, model, data={"input_range": [0.0, 2.0], "effective_input_range": [float(x.min()), float(x.max())]})
    return path


def test_control_and_sweep_warn_when_the_drive_leaves_the_fitted_range(tmp_path, narrow_model, capsys):
    loop = ["--model", str(narrow_model), "--kp", "0.5", "--ki", "2", "--duration", "6", "--dt", "0.05"]
    assert main(["control", *loop, "--out", str(tmp_path / "c")]) == 0
    err = capsys.readouterr().err
    assert "warning: plant model: input 'drive u' leaves the range the model was fitted on" in err
    m = json.loads((tmp_path / "c" / "metrics.json").read_text())
    u = np.genfromtxt(tmp_path / "c" / "trajectory.csv", delimiter=",", names=True)["u"]
    assert m["u_max_V"] == pytest.approx(u.max()) and m["u_min_V"] == pytest.approx(u.min())
    raw = m["range_checks"][0]
    assert raw["n_above"] == int(np.sum(u > 2.0)) > 0 and raw["exits"][0]["start_s"] == pytest.approx(
        0.05 * np.flatnonzero(u > 2.0)[0]
    )
    assert m["range_checks"][1]["what"] == "effective input"
    assert main(["sweep", *loop, "--x", "kp=0.05,0.5", "--y", "ki=0.01,2", "--out", str(tmp_path / "sw")]) == 0
    err = capsys.readouterr().err
    s = json.loads((tmp_path / "sw" / "metrics.json").read_text())["range_check"]
    rows = np.genfromtxt(tmp_path / "sw" / "sweep.csv", delimiter=",", names=True)
    # exits under 1 % of the fitted span are not counted (the tolerance of every range check)
    assert s["tolerance"] == pytest.approx(0.01 * (s["fitted_range"][1] - s["fitted_range"][0]))
    assert s["n_outside"] == int(np.sum(rows["u_max_V"] > 2.0 + s["tolerance"])) and s["n_configurations"] == 4
    assert (s["n_outside"] > 0) == ("configurations drive the plant model outside" in err)


def _ramp(a, b, n):
    return np.linspace(a, b, n)


def test_branch_check_flags_a_branch_training_never_walked():
    from smafl_jax.models import branch_check, trained_branches

    up = _ramp(0.0, 1.0, 400)
    trained = trained_branches(up)  # training only ever rose through [0, 1]
    assert trained["falling"] == [0]  # only the first sample (before any move) counts for both branches
    assert branch_check(up, trained)["n_untrained"] == 0  # its own trajectory
    down = np.concatenate([up, _ramp(1.0, 0.0, 400)])
    c = branch_check(down, trained, dt=0.1)
    # the falling half lies inside the range but on the untrained branch (minus the deadband before it reads "falling")
    assert 0.45 < c["fraction_untrained"] <= 0.5 and c["by_direction"]["rising"] == 0
    assert "walks branches its training never visited" in c["warning"] and "mostly falling" in c["warning"]
    assert 0.9 <= c["untrained_span_fraction"] <= 1.0
    # however briefly: a quick dip back through 30 % of the span is flagged, a dip within the 2 % deadband is not
    dip = np.concatenate([up, _ramp(1.0, 0.7, 20)])
    assert 0.2 <= branch_check(dip, trained)["untrained_span_fraction"] and "warning" in branch_check(dip, trained)
    assert "warning" not in branch_check(np.concatenate([up, _ramp(1.0, 0.985, 5)]), trained)
    # a training record that rose and fell covers both: the same new drive is fine
    both = trained_branches(np.concatenate([up, _ramp(1.0, 0.0, 400)]))
    assert branch_check(down, both)["n_untrained"] == 0 and "warning" not in branch_check(down, both)
    # samples outside the trained range are the range check's business, not counted here
    assert branch_check(_ramp(2.0, 3.0, 50), trained)["n_inside"] == 0
    assert not branch_check(down, None)["checked"]


def test_simulate_warns_on_an_untrained_branch(tmp_path, capsys):
    model = sj.load_model(DATASETS / "truth.json")
    dt = 0.05
    heat = np.repeat(np.linspace(0.5, 3.0, 6), 400)  # a staircase that only ever heats
    x = np.asarray(model.hysteresis_input(heat, dt))
    path = tmp_path / "heated.json"
    sj.save_model(
        path, model, data={"input_range": [0.5, 3.0], "effective_input_range": [float(x.min()), float(x.max())],
                           "trained_branches": sj.models.trained_branches(x)},
    )  # fmt: skip
    cool = np.concatenate([heat, heat[::-1][400:]])  # the same levels back down: in range, on the cooling branch
    csv = tmp_path / "cool.csv"
    measured = np.asarray(sj.simulate(model, cool, dt))  # --metrics scores against a measured column
    sj.atomic_write_csv(csv, {"time_s": np.arange(cool.size) * dt, "voltage_V": cool, "displacement_mm": measured})
    metrics = tmp_path / "m.json"
    argv = ["simulate", str(path), str(csv), "--out", str(tmp_path / "out.csv"), "--metrics", str(metrics)]
    assert main([*argv, "--measured", "displacement_mm"]) == 0
    err = capsys.readouterr().err
    assert "walks branches its training never visited" in err and "leaves the range" not in err
    chk = json.loads(metrics.read_text())["branch_check"]
    assert chk["checked"] and chk["by_direction"]["falling"] > 0 and chk["untrained_span_fraction"] >= 0.1
    csv2 = tmp_path / "heat.csv"
    sj.atomic_write_csv(csv2, {"time_s": np.arange(heat.size) * dt, "voltage_V": heat})
    assert main(["simulate", str(path), str(csv2), "--out", str(tmp_path / "out2.csv")]) == 0
    assert "never visited" not in capsys.readouterr().err


def test_trained_effective_range_holds_the_fitted_start_state():
    """A cold (or at-rest) start is a state the fit saw; the first sample is already a step warmer.  Without the start in
    the trained range, a new record resting at that state read as "outside the trained range" (trial 5)."""
    import dataclasses

    from smafl_jax.effects import ExtendedModel
    from smafl_jax.models import effective_range

    truth = sj.load_model(DATASETS / "truth.json")
    cold = dataclasses.replace(truth, thermal=dataclasses.replace(truth.thermal, init="ambient"))
    dt = 0.05
    u = np.full(400, 3.0)  # power on from the first sample, from cold
    x = np.asarray(cold.hysteresis_input(u, dt))
    assert x[0] > 0.01 * (x.max() - x.min())  # the first sample is already well above the cold start
    rng = effective_range([(cold, u, dt, None)])
    assert rng == pytest.approx([0.0, x.max()], abs=1e-12)
    # a new record resting cold before the same step is inside it (it warned against the samples-only range)
    x_new = np.asarray(cold.hysteresis_input(np.concatenate([np.zeros(40), u]), dt))
    assert "warning" not in range_check(x_new, rng, what="effective input")
    assert "warning" in range_check(x_new, [float(x.min()), float(x.max())], what="effective input")
    # a segment whose first sample was not fitted adds no start; the extended model agrees with its base
    mask = np.arange(u.size) >= 10
    assert effective_range([(cold, u, dt, mask)]) == pytest.approx([x[mask].min(), x.max()], rel=1e-12)
    assert effective_range([(ExtendedModel(cold, ()), u, dt, None)]) == pytest.approx(rng, abs=1e-12)
    assert float(ExtendedModel(truth, ()).hysteresis_start(u, dt)) == pytest.approx(float(truth.hysteresis_start(u, dt)))
