"""`smafl fit --model cascade-NAME`: any registered hysteresis class behind the Joule thermal lag.

The classes declare how they are fitted (`AbstractHysteresis.for_cascade`, `refine_jointly`); the fit asks them.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax import UserInputError
from smafl_jax.models import Cascade, JouleThermal, Preisach, hysteresis_class, hysteresis_models
from smafl_jax.report import HYSTERESIS, MODELS, build_model, fit_record

DT = 0.2


def _drive(rng, n):
    """Slow random levels with ramps between them, 0..3 V."""
    levels = rng.uniform(0.0, 3.0, n // 40 + 1)
    return np.clip(np.repeat(levels, 40)[:n] + 0.05 * rng.standard_normal(n), 0.0, None)


def _record(rng, n=600, noise=0.002):
    """A record of a Preisach cascade (weights drawn at random): the class's own structure, for the fit's plumbing."""
    h = Preisach.from_range(0.0, 3.0, n_levels=6)
    w = rng.uniform(0.0, 0.2, h.n_relays)
    truth = Cascade(thermal=JouleThermal(k1=jnp.asarray(0.4)), hysteresis=h.with_linear_weights(jnp.asarray([*w, 0.1])))
    u = _drive(rng, n)
    y = np.asarray(truth.simulate(jnp.asarray(u), DT)) + noise * rng.standard_normal(n)
    return sj.Record.from_arrays(DT * np.arange(n), u, y, input_name="voltage_V", output_name="displacement_mm")


def test_every_registered_class_has_a_cascade_model_name():
    others = [k for k in HYSTERESIS if k != "eupi"]
    assert others and all(f"cascade-{k}" in MODELS for k in others)


@pytest.mark.parametrize("cls", hysteresis_models(), ids=lambda c: c.__name__)
def test_for_cascade_covers_the_drive_range_from_zero(cls):
    h = cls.for_cascade(4.0)
    assert type(h) is cls and float(h.u_ref) == 0.0 and float(h.u_ref + h.u_span) == pytest.approx(4.0)


def test_build_model_puts_the_class_behind_the_thermal_lag(rng):
    rec = _record(rng, n=100)
    m = build_model("cascade-preisach", rec)
    assert isinstance(m, Cascade) and type(m.hysteresis) is hysteresis_class("preisach")
    assert m.hysteresis.n_levels == Preisach.CASCADE_LEVELS
    assert float(m.hysteresis.u_span) == pytest.approx(float(rec.u.max()))
    neg = sj.Record.from_arrays(
        rec.time, rec.u - float(rec.u.max()), rec.y, input_name="voltage_V", output_name="displacement_mm"
    )
    with pytest.raises(UserInputError, match="cascade-preisach needs a drive voltage >= 0"):
        build_model("cascade-preisach", neg)


@pytest.mark.slow  # suite time (29-94 s on 2 cores); the default suite fits a Preisach cascade in test_protocol_dispatch
def test_preisach_cascade_fit_is_the_profiled_start_and_predicts_held_out():
    rec = _record(np.random.default_rng(1))  # a seed whose held-out block stays on trained branches (coverage 0.97)
    model, doc, _ = fit_record(rec, model="cascade-preisach", orientation="rises", memory="rule", refit=False)
    assert isinstance(model, Cascade) and type(model.hysteresis) is Preisach
    # screened on the coarser grid, finished on the model's own
    assert model.hysteresis.n_levels == Preisach.CASCADE_LEVELS > Preisach.SCREEN_LEVELS
    # the class declares its profiled start the fit: no LM steps, and the fit says so
    assert doc["solver"]["n_steps"] == 0 and doc["settings"]["max_steps"] == 0
    assert any(n.startswith("no joint refinement: Preisach") for n in doc["notes"])
    # the thermal rate is found by the profile; the training part is fitted to the noise (0.002) on a grid that is not
    # the plant's (12 levels vs 6), and the held-out block to a few percent of the stroke (measured: 0.0021, 0.0123)
    assert float(model.thermal.k1) == pytest.approx(0.4, rel=0.25)
    assert doc["metrics"]["train"]["rmse"] < 0.003
    assert doc["metrics"]["validation"]["rmse"] < 0.02 * np.ptp(rec.y)


def test_only_the_eupi_cascade_gets_a_joint_refinement():
    """The rule `fit_record` applies (the fit above checks it on a fitted Preisach cascade; this one runs by default):
    an EUPI cascade keeps its joint refinement, a Preisach cascade declares its profiled start the fit."""
    from smafl_jax.report._report_fit import joint_steps  # private: the refinement rule fit_record applies

    rec = _record(np.random.default_rng(1))
    notes = []
    assert joint_steps(build_model("cascade", rec), 3, notes) == 3 and notes == []
    preisach = build_model("cascade-preisach", rec)
    assert type(preisach.hysteresis) is Preisach
    assert joint_steps(preisach, 3, notes) == 0 and notes[0].startswith("no joint refinement: Preisach")


@pytest.mark.slow  # suite time: about 60 s more than the split-only fit above (the whole-record screening and refit)
def test_preisach_cascade_whole_record_refit_fits_every_sample():
    rec = _record(np.random.default_rng(1))
    model, doc, _ = fit_record(rec, model="cascade-preisach", orientation="rises", memory="rule")
    # the saved model, refitted on every sample (fresh screening, or the split fit's thermal state: `_warm_refit`)
    assert doc["metrics"]["whole_record"]["rmse"] < 0.003 and model.hysteresis.n_levels == Preisach.CASCADE_LEVELS


@pytest.mark.parametrize("cls", hysteresis_models(), ids=lambda c: c.__name__)
def test_screening_grid_keeps_range_orientation_and_rule_and_goes_back(cls):
    h = cls.from_range(0.5, 4.0)
    h = dataclasses.replace(h, orientation=-1).with_init(cls.RULE_INITS[-1])
    coarse = h.screening_grid()  # may be another class (GaussianPreisach screens on a free relay grid)
    assert coarse.orientation == -1 and coarse.init == h.init
    assert float(coarse.u_ref) == pytest.approx(float(h.u_ref)) and float(coarse.u_span) == pytest.approx(float(h.u_span))
    starts = h.adopt(coarse)  # the screened model goes back to this structure
    assert starts and all(type(b) is type(h) and b.orientation == -1 and b.init == h.init for b in starts)
    assert all(np.shape(b.linear_weights()) == np.shape(h.linear_weights()) for b in starts)
    if coarse is h:  # a class screened on its own grid
        assert starts == (h,)
