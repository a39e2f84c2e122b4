"""A fitted model's input held to its trained range (`AbstractHysteresis.with_held`, ``fit_record(hold_input=)``)."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax import UserInputError
from smafl_jax.models import hysteresis_models
from smafl_jax.report import fit_record

DATASETS = Path(__file__).resolve().parents[1] / "datasets"
LO, HI = 0.5, 1.6


def _random_model(cls, rng):
    """``cls`` on [0, 2] with random weights (non-negative where the class needs them)."""
    m = cls.from_range(0.0, 2.0)
    w = rng.normal(size=np.shape(m.linear_weights()))
    w = np.where(np.asarray(m.nonnegative_columns()), np.abs(w), w)
    return m.with_linear_weights(w)


@pytest.mark.parametrize("cls", hysteresis_models(), ids=lambda c: c.__name__)
def test_a_held_model_is_the_model_on_the_clipped_input(cls, rng):
    """Every class: held to [lo, hi] = the same model run on ``clip(u, lo, hi)``, by its whole-record form and by its
    per-sample step (the closed loop's form); on an input inside the range nothing changes."""
    m = _random_model(cls, rng)
    held = m.with_held(LO, HI)
    u = 1.0 + 0.9 * np.sin(np.linspace(0.0, 9.0, 300)) + 0.2 * rng.normal(size=300)  # leaves [0.5, 1.6] both ways
    want = np.asarray(sj.simulate(m, np.clip(u, LO, HI)))
    np.testing.assert_allclose(np.asarray(sj.simulate(held, u)), want, rtol=0, atol=1e-12)
    state, steps = held.initial_state(u[0]), []
    for x in u:  # a plain loop over the pure step
        state, y = held.step(state, x)
        steps.append(float(y))
    np.testing.assert_allclose(steps, want, rtol=0, atol=1e-10)
    inside = np.clip(u, LO, HI)
    np.testing.assert_array_equal(np.asarray(sj.simulate(held, inside)), np.asarray(sj.simulate(m, inside)))
    assert np.any(np.abs(np.asarray(sj.simulate(m, u)) - want) > 1e-6)  # the record does leave the range


def test_held_range_saves_loads_and_is_described(tmp_path, rng):
    m = _random_model(sj.EUPI, rng).with_held(LO, HI)
    path = tmp_path / "m.json"
    sj.save_model(path, m)
    back = sj.load_model(path)
    assert back.held == (LO, HI)
    assert any("input held to its trained range [0.5, 1.6]" in line for line in back.describe())
    assert back.with_held(None).held is None
    assert back.with_held(LO, None).held == (LO, None) and back.with_held(None, HI).held == (None, HI)
    for bad in ((1.0, 1.0), (2.0, 1.0), (np.nan, 1.0), (np.inf, None)):
        with pytest.raises(ValueError, match="held range"):
            m.with_held(*bad)


@pytest.fixture(scope="module")
def temperature_record(tmp_path_factory, direct_record_csv):
    """A temperature-driven record of the independent direct-input plant."""
    path = tmp_path_factory.mktemp("hold") / "t.csv"
    return direct_record_csv(path, 3, "temperature_C", n=500, dt=0.1, u_lo=25.0, u_span=50.0)


@pytest.mark.slow  # suite time (session 70: 15-260 s on 2 cores)
def test_fit_holds_a_directly_measured_input_unless_its_validation_says_otherwise(temperature_record):
    opts = dict(model="eupi", max_steps=3, refit=False)
    model, doc, (train, _, _) = fit_record(temperature_record, hold_input="on", **opts)
    entry = doc["settings"]["hold_input"]
    assert entry["rule"] == "on" and entry["of"] == "input_range"
    assert model.held == tuple(entry["held"]) == tuple(doc["data"]["input_range"])
    assert sj.model_from_dict(doc["model"]).held == model.held  # fit.json saves the held model
    off, doc_off, _ = fit_record(temperature_record, hold_input="off", **opts)
    assert off.held is None and doc_off["settings"]["hold_input"]["held"] is None
    # on the samples it was fitted on the held model is the fitted one: the range is theirs
    u = temperature_record.u[train]
    np.testing.assert_array_equal(np.asarray(sj.simulate(model, u)), np.asarray(sj.simulate(off, u)))
    # auto: held, unless the validation samples (here beyond the training part's range) are predicted better extrapolating
    auto, doc_auto, _ = fit_record(temperature_record, **opts)
    check = doc_auto["settings"]["hold_input_check"]
    assert check["on"] == "the validation samples" and check["rmse_held"] != check["rmse_extrapolating"]
    better = "extrapolating" if check["rmse_extrapolating"] < check["rmse_held"] else "held"
    assert check["chosen"] == better and (auto.held is None) == (better == "extrapolating")
    assert doc_auto["metrics"]["validation"]["rmse"] == pytest.approx(min(check["rmse_held"], check["rmse_extrapolating"]))
    with pytest.raises(UserInputError, match="hold_input"):
        fit_record(temperature_record, hold_input="yes", **opts)


@pytest.mark.slow  # suite time (session 70: 15-260 s on 2 cores)
def test_a_cascade_is_held_below_its_trained_thermal_range_only(tmp_path):
    """auto holds a cascade's thermal state at the low edge of its trained range (colder than ever trained: no
    extrapolation) and lets it extrapolate above; on holds both sides; a record that reached the ambient holds nothing."""
    rec = sj.load_record(DATASETS / "main_loop.csv")
    opts = dict(model="cascade", max_steps=0, refit=False, orientation="rises", sees="voltage", thermal_start="steady",
                memory="descended")  # fmt: skip
    model, doc, _ = fit_record(rec, **opts)  # starts at rest at 0 V: the ambient is in its range
    assert model.hysteresis.held is None and "ambient" in doc["settings"]["hold_input"]["why"]
    # the same drive from its first rise at 1.7 V to the next fall through it: never colder than the steady start
    part = slice(132, 749)
    warm = sj.Record.from_arrays(rec.time[part] - rec.time[part][0], rec.u[part], rec.y[part], input_name="voltage_V",
                                 output_name="displacement_mm")  # fmt: skip
    model, doc, _ = fit_record(warm, **opts)
    lo = doc["data"]["effective_input_range"][0]
    assert lo > 0 and model.hysteresis.held == (lo, None) and doc["settings"]["hold_input"]["held"] == [lo, None]
    on, doc_on, _ = fit_record(warm, hold_input="on", **opts)
    assert on.hysteresis.held == tuple(doc_on["data"]["effective_input_range"])
    off, _, _ = fit_record(warm, hold_input="off", **opts)
    assert off.hysteresis.held is None
    # below: the held model is the model on the held thermal state; above and inside it extrapolates as fitted
    u = np.r_[warm.u, np.zeros(200), warm.u, np.full(100, warm.u.max() + 1.5)]
    theta = np.asarray(model.hysteresis_input(u, warm.dt))
    want = np.asarray(off.hysteresis.simulate(np.maximum(theta, lo)))
    np.testing.assert_allclose(np.asarray(sj.simulate(model, u, warm.dt)), want, rtol=0, atol=1e-10)
    assert np.max(np.abs(np.asarray(sj.simulate(off, u, warm.dt)) - want)) > 1e-6  # the drive does go colder
    # simulate says which side is held; a JSON round trip keeps the open side
    path = tmp_path / "fit.json"
    sj.save_model(path, model, data=doc["data"], settings=doc["settings"])
    csv = tmp_path / "cold.csv"
    sj.atomic_write_csv(csv, {"time_s": np.arange(u.size) * warm.dt, "voltage_V": u})
    warned = [w for w in sj.simulate_record(path, csv).warnings if w.startswith("effective input")]
    assert warned and all("below that range the model holds its hysteresis input" in w for w in warned)
    assert json.loads(path.read_text())["model"]["hysteresis"]["held"] == [lo, None]
    assert sj.load_model(path).hysteresis.held == (lo, None)
    assert any("held at or above" in line for line in sj.load_model(path).describe())


@pytest.mark.slow  # suite time (session 70: 15-260 s on 2 cores)
def test_leave_one_record_out_scores_the_held_fold_model(tmp_path):
    """A joint fit's folds are held to their own training records' range, as the saved model is: a held-out record
    that leaves that range is predicted alike up to its first exit and differently after it."""
    sys.path.insert(0, str(Path(__file__).parent))
    import indep_direct

    recs = []
    for seed, lo, span in ((3, 25.0, 50.0), (4, 25.0, 50.0), (5, 25.0, 70.0)):  # the last one goes above the others
        r = indep_direct.make_record(seed, "preisach", "steps", n=300, dt=0.1, u_lo=lo, u_span=span)
        recs.append(sj.Record.from_arrays(r["t"], r["u"], r["y"], input_name="temperature_C", output_name="x_mm"))
    opts = dict(model="eupi", max_steps=2)
    _, doc, held = sj.fit_records(recs, hold_input="on", **opts)
    _, doc_off, free = sj.fit_records(recs, hold_input="off", **opts)
    auto, doc_auto, _ = sj.fit_records(recs, **opts)  # auto: the folds' pooled held-out error decides
    check = doc_auto["settings"]["hold_input_check"]
    better = "extrapolating" if check["rmse_extrapolating"] < check["rmse_held"] else "held"
    assert check["on"] == "the leave-one-record-out folds" and check["chosen"] == better
    assert (auto.held is None) == (better == "extrapolating")
    assert doc["settings"]["hold_input"]["held"] == doc["data"]["input_range"]
    assert doc_off["settings"]["hold_input"]["held"] is None
    lo, hi = (min(r.u.min() for r in recs[:2]), max(r.u.max() for r in recs[:2]))
    u = recs[2].u
    first = int(np.argmax((u < lo) | (u > hi)))
    assert first > 0
    a, b = held["yhat_loro"][2], free["yhat_loro"][2]
    np.testing.assert_array_equal(a[:first], b[:first])
    assert np.max(np.abs(a[first:] - b[first:])) > 1e-6
    with pytest.raises(UserInputError, match="hold_input"):
        sj.fit_records(recs, hold_input="sometimes", **opts)


@pytest.mark.slow  # suite time (session 70: 15-260 s on 2 cores)
def test_the_split_model_is_scored_held_to_its_training_part(temperature_record):
    """The validation error (and the class comparison) is that of the split model as it would be saved: held to the
    range of its own training samples, while the saved model is held to the whole record's."""
    model, doc, (train, val, _) = fit_record(temperature_record, model="eupi", max_steps=3, hold_input="on")
    u = temperature_record.u
    split = sj.model_from_dict(doc["split_model"])
    assert split.held == (float(u[train].min()), float(u[train].max()))
    assert model.held == (float(u.min()), float(u.max()))
    want = sj.metrics(temperature_record.y[val], np.asarray(sj.simulate(split, u))[val])["rmse"]
    assert doc["metrics"]["validation"]["rmse"] == pytest.approx(want, rel=1e-9)
