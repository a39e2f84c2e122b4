"""Per-record thermal starts of a joint fit (`JouleThermal.with_record_starts`, `for_record`,
smafl_jax.identify._record_starts): each of several records runs from its own thermal state."""

import sys
from pathlib import Path

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.identify._record_starts import fit_record_starts  # private: the start search itself is under test

sys.path.insert(0, str(Path(__file__).parent))
import indep_plant as ip

DT, K1 = 0.1, 0.1


def _hysteresis():
    h = sj.Cascade.from_range(4.0, n_sym=2, n_alpha=1, n_asym=2, poly_order=2).hysteresis
    return h.with_linear_weights(np.array([0.3, 1.0, 0.5, 0.2, 0.1, 0.05, 0.2]))


def _plant(u0):
    return sj.Cascade(thermal=sj.JouleThermal(k1=K1, k2=0.05, init="given", u0=u0), hysteresis=_hysteresis())


def _drive(rng, n):
    t = np.arange(n) * DT
    return np.clip(2.0 + 1.5 * np.sin(2 * np.pi * t / 40.0 + rng.uniform(0, 6)), 0.0, None)


def test_each_record_runs_from_its_own_start_and_plain_simulate_refuses(tmp_path, rng):
    u = _drive(rng, 400)
    model = _plant(1.0).with_record_starts([0.2, 3.0])
    assert model.thermal.n_record_starts == 2 and _plant(1.0).thermal.n_record_starts is None
    for i, u0 in enumerate((0.2, 3.0)):
        np.testing.assert_array_equal(model.for_record(i).simulate(u, DT), _plant(u0).simulate(u, DT))
    with pytest.raises(sj.UserInputError, match="one start per record"):
        model.simulate(u, DT)
    assert "fitted per record" in " ".join(model.describe())
    sj.save_model(tmp_path / "m.json", model)
    back = sj.load_model(tmp_path / "m.json")
    np.testing.assert_array_equal(np.asarray(back.thermal.u0), [0.2, 3.0])
    with pytest.raises(ValueError, match="scalar or one value per record"):
        sj.JouleThermal(init="given", u0=np.ones((2, 2)))


@pytest.mark.slow  # suite time (session 70: 15-260 s on 2 cores)
def test_fit_recovers_each_records_start(rng):
    """Known truth, the fit's own model class: two records of one plant, one cold and one warm; the joint
    refinement trains the per-record starts with the rate and the gains."""
    n, noise = 1200, 0.002
    truth = (0.2, 3.0)
    data = []
    for u0 in truth:
        u = _drive(rng, n)
        data.append((u, np.asarray(_plant(u0).simulate(u, DT)) + noise * rng.standard_normal(n), DT))
    plant = _plant(1.5)
    start = sj.Cascade(thermal=sj.JouleThermal(k1=0.07, k2=0.05), hysteresis=plant.hysteresis).with_record_starts([1.5, 1.5])
    res = sj.fit(start, data, init="linear", max_steps=200)
    assert np.asarray(res.model.thermal.u0) == pytest.approx(truth, abs=0.05)
    assert float(res.model.thermal.k1) == pytest.approx(K1, rel=0.02)
    rmse = np.sqrt(2 * res.loss / (2 * n))
    assert rmse < 1.2 * noise


@pytest.mark.slow  # suite time (69 s, two joint fits); the screening on these records runs in the default suite below
def test_joint_fit_of_a_warm_and_a_cold_record_from_an_independent_plant():
    """One independent plant (tests/indep_plant.py, no smafl_jax), a cold PWM record and a warm multisine record: with
    one start per record the joint fit holds its training error near the noise and starts the warm record warmer;
    with one shared start (the earlier behaviour, `thermal_start="steady"`) it cannot."""
    recs = []
    for name, drive, start in (("pwm_cold", "pwm", "cold"), ("ms_warm", "multisine", "warm")):
        r = ip.make_record(31, drive=drive, rate_hz=10, minutes=4.0, start=start)
        recs.append(sj.Record.from_arrays(r["time"], r["u"], r["y"], name=name))
    noise = ip.make_record(31, drive="pwm", rate_hz=10, minutes=4.0, start="cold")["noise_sd"]
    saved, doc, details = sj.fit_records(recs, model="cascade", split="none")
    starts = {row["record"]: row["u0_V"] for row in doc["per_record_start"]}
    assert starts["ms_warm"] > 2.0 * starts["pwm_cold"]
    fitted = details["record_model"]
    assert fitted.thermal.n_record_starts == 2 and saved.thermal.n_record_starts is None
    np.testing.assert_allclose(fitted.for_record(1).simulate(recs[1].u, recs[1].dt), details["yhat"][1], rtol=1e-9, atol=1e-12)
    per_record = doc["settings"]["start_screening"]
    assert any(row.get("thermal_start") == "per record" for row in per_record)
    _, shared, _ = sj.fit_records(recs, model="cascade", split="none", thermal_start="steady")
    assert doc["metrics"]["train"]["rmse"] < 1.5 * noise
    assert doc["metrics"]["train"]["rmse"] < 0.5 * shared["metrics"]["train"]["rmse"]


def test_start_screening_moves_a_cold_record_off_the_steady_rule_on_an_independent_plant():
    """The start screening alone (`fit_record_starts`), on the records of the slow joint-fit test above: the cold PWM
    record, whose first sample is a pulse, leaves the shared steady rule's hot start for the coldest candidate, and the
    profiled loss falls more than tenfold.  (The screening leaves the warm record cold too at 4 minutes; the joint
    refinement trains it warm, which the slow test checks.)"""
    data = []
    for drive, start in (("pwm", "cold"), ("multisine", "warm")):
        r = ip.make_record(31, drive=drive, rate_hz=10, minutes=4.0, start=start)
        data.append((r["u"], r["y"], float(r["time"][1] - r["time"][0])))
    u_hi = max(float(np.max(u)) for u, _, _ in data)
    model, info = fit_record_starts(sj.Cascade.from_range(u_hi), data)
    assert info["shared_u0"][0] > 0.5 * u_hi  # the steady rule starts the cold record hot (its first sample is a pulse)
    assert info["u0"][0] < 0.1 * u_hi and model.thermal.n_record_starts == 2
    assert info["profiled_loss"] < 0.1 * info["profiled_loss_shared"]


def test_record_starts_need_several_records_and_a_thermal_stage(rng):
    u = _drive(rng, 200)
    y = np.asarray(_plant(1.0).simulate(u, DT))
    assert fit_record_starts(_plant(1.0), [(u, y, DT)]) is None
    assert fit_record_starts(_hysteresis(), [(u, y, DT), (u, y, DT)]) is None


def test_heldout_record_starts_from_its_own_first_window(rng):
    """Leave-one-record-out: a held-out record of a cascade starts from the start estimated on its first window and is
    scored after it (`_heldout`); the trained start's whole-record error is kept beside it."""
    from smafl_jax.identify._multi_record import _heldout  # private: the held-out rule itself is under test

    n = 1200
    u = _drive(rng, n)
    warm = _plant(3.5)
    rec = sj.Record.from_arrays(np.arange(n) * DT, u, np.asarray(warm.simulate(u, DT)), name="warm")
    cold = _plant(1.5).with_record_starts([0.2, 0.2])
    info = {"record_starts": {"shared_rule": ["given", 0.2]}}
    y, scored, start = _heldout(cold, info, rec)
    assert start["rule"].startswith("estimated") and start["thermal"] != "fit"
    assert not scored[: start["window_samples"]].any() and scored[start["window_samples"] :].all()
    err = np.sqrt(np.mean((y[scored] - rec.y[scored]) ** 2))
    assert err < 0.2 * start["shared_start_whole"]["rmse"]
    # no thermal stage: the fitted start, scored whole
    h = _hysteresis()
    y2, scored2, start2 = _heldout(h, {}, rec)
    assert scored2.all() and "scored whole" in start2["rule"]
    np.testing.assert_allclose(y2, h.simulate(u))


@pytest.mark.slow  # suite time (session 71: 12 s under load); the held-out record's own first window is scored in the default suite
def test_heldout_record_shorter_than_its_window_is_scored_whole(rng):
    from smafl_jax.identify._multi_record import _heldout  # private: the held-out rule itself is under test

    n = 40  # 4 s: shorter than 5 thermal time constants (50 s)
    u = _drive(rng, n)
    rec = sj.Record.from_arrays(np.arange(n) * DT, u, np.asarray(_plant(3.5).simulate(u, DT)), name="short")
    y, scored, start = _heldout(_plant(1.5), {}, rec)
    assert scored.all() and start["rule"].endswith("scored whole") and np.all(np.isfinite(y))


def test_simulating_a_training_record_of_a_joint_fit_uses_its_own_start(tmp_path, rng):
    """`smafl simulate fit.json A.csv` with A a training record of a joint fit (same file content): A's own fitted
    start and memory rule, not the shared rule the saved model carries; another record keeps the shared rule."""
    n = 300
    shared = _plant(0.2)
    paths = []
    for name in ("a", "b"):
        u = _drive(rng, n)
        data = np.column_stack([np.arange(n) * DT, u, np.asarray(_plant(3.0).simulate(u, DT))])
        paths.append(tmp_path / f"{name}.csv")
        np.savetxt(paths[-1], data, delimiter=",", header="time_s,voltage_V,displacement_mm", comments="")
    rec_a = sj.load_record(paths[0])
    sj.save_model(
        tmp_path / "fit.json",
        shared,
        data={
            "records": [{"name": "a", "sha256": rec_a.sha256}],
            "input_column": "voltage_V",
            "output_column": "displacement_mm",
        },
        per_record_start=[{"record": "a", "u0_V": 3.0, "memory": "zero"}],
    )
    got = sj.simulate_record(tmp_path / "fit.json", paths[0])
    own = shared.with_thermal_start("given", 3.0)
    own = own.with_hysteresis(own.hysteresis.with_init("zero"))
    np.testing.assert_allclose(got.y, own.simulate(rec_a.u, rec_a.dt), rtol=1e-12, atol=1e-12)
    assert any("training record a" in t for t in got.notes)
    other = sj.simulate_record(tmp_path / "fit.json", paths[1])
    rec_b = sj.load_record(paths[1])
    np.testing.assert_allclose(other.y, shared.simulate(rec_b.u, rec_b.dt), rtol=1e-12, atol=1e-12)


@pytest.mark.slow  # suite time (19 s, the sample CLI on three records); the posterior's start rule runs in the default suite below
def test_sample_on_several_records_runs_each_from_its_own_start(tmp_path, rng, capsys):
    """`smafl sample A.csv B.csv C.csv --fit fit.json`: one posterior over all records; training records of the joint fit
    (same file content) start from their own fitted starts, another record by the fit's shared rule; the predictive
    check runs each record from its start (one panel per record, a record column in predictive.csv)."""
    from smafl_jax.cli import main

    n, starts = 300, {"a": 0.2, "b": 3.0, "c": 1.0}  # c: not a training record, started by the shared rule (1.0 V)
    shared = _plant(1.0)
    paths, truth = {}, {}
    for name, u0 in starts.items():
        u = _drive(rng, n)
        truth[name] = np.asarray(_plant(u0).simulate(u, DT))
        data = np.column_stack([np.arange(n) * DT, u, truth[name] + 0.01 * rng.standard_normal(n)])
        paths[name] = tmp_path / f"{name}.csv"
        np.savetxt(paths[name], data, delimiter=",", header="time_s,voltage_V,displacement_mm", comments="")
    recs = {k: sj.load_record(p) for k, p in paths.items()}
    sj.save_model(
        tmp_path / "fit.json",
        shared,
        data={
            "records": [{"name": k, "sha256": recs[k].sha256} for k in ("a", "b")],
            "input_column": "voltage_V",
            "output_column": "displacement_mm",
        },
        per_record_start=[{"record": "a", "u0_V": 0.2}, {"record": "b", "u0_V": 3.0}],
    )
    out = tmp_path / "post"
    argv = ["sample", *(str(paths[k]) for k in "abc"), "--fit", str(tmp_path / "fit.json"), "--out", str(out)]
    argv += ["--steps", "20", "--walkers", "26", "--draws", "8", "--linear", "sample", "--no-progress"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    summary = __import__("json").loads((out / "summary.json").read_text())
    assert {"thermal.u0[0]", "thermal.u0[1]", "thermal.u0[2]"} <= set(summary["parameters"])
    rows = summary["data"]["records"]
    assert [r["file"] for r in rows] == ["a.csv", "b.csv", "c.csv"]
    assert "own start in the joint fit (record b): 3 V" in rows[1]["start"] and "start rule" in rows[2]["start"]
    assert set(summary["heldout_coverage_95_per_record"]) == {"a.csv", "b.csv", "c.csv"} and "b.csv:" in printed
    table = np.genfromtxt(out / "predictive.csv", delimiter=",", names=True)
    for k, name in enumerate("abc"):
        median = table["median"][table["record"] == k]
        # walkers stay near the fit in 20 steps: each record's prediction follows its own start, not the shared one
        err_own = np.max(np.abs(median[:50] - truth[name][:50]))
        err_shared = np.max(np.abs(np.asarray(shared.simulate(recs[name].u, DT))[:50] - truth[name][:50]))
        assert err_own < 0.05 and (name == "c" or err_own < 0.2 * err_shared), (name, err_own, err_shared)
    for png in ("predictive_time.png", "predictive_loop.png"):
        assert (out / png).stat().st_size > 0


def test_posterior_predicts_a_new_record_by_the_shared_start_rule(rng):
    """`Posterior(new_record_start=(init, u0, memory))`: a record outside the data (``record=None``) runs from the joint
    fit's shared rule, thermal start and operator memory; record i of the data from its own start."""
    u = [_drive(rng, 200) for _ in range(3)]
    model = _plant(1.0).with_record_starts([0.2, 3.0], ["descended", "from_top"])
    data = [
        (x, np.asarray(model.for_record(i).simulate(x, DT)) + 0.01 * rng.standard_normal(200), DT) for i, x in enumerate(u[:2])
    ]
    post = sj.Posterior(model, data, linear="sample", new_record_start=("given", 1.0, "zero"))
    theta = post.theta0[None, :]
    shared = _plant(1.0).with_hysteresis(_hysteresis().with_init("zero"))
    f_new, _ = post.predict(theta, u[2], DT, rng)
    np.testing.assert_allclose(f_new[0], shared.simulate(u[2], DT), rtol=1e-10, atol=1e-10)
    f_own, _ = post.predict(theta, u[1], DT, rng, record=1)
    np.testing.assert_allclose(f_own[0], model.for_record(1).simulate(u[1], DT), rtol=1e-10, atol=1e-10)
    with pytest.raises(sj.UserInputError, match="record must be in"):
        post.predict(theta, u[1], DT, rng, record=2)
