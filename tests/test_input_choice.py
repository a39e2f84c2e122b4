"""The cascade's hysteresis input (effective voltage or heat): both refined, the validation samples choose (session 49).

Records from tests/indep_plant.py (plain numpy, no smafl_jax import).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.report import fit_record

sys.path.insert(0, str(Path(__file__).resolve().parent))
import indep_plant

SMALL = dict(n_sym=4, n_alpha=2, n_asym=2, poly_order=3)


def _record(tmp_path):
    r = indep_plant.make_record(
        7, drive="multisine", rate_hz=10.0, minutes=2.0, start="warm", orientation="displacement", hyst_input="temperature",
        n_ops=3, noise=0.005,
    )  # fmt: skip
    path = tmp_path / "heat.csv"
    indep_plant.write_csv(path, r)
    return sj.load_record(path)


@pytest.mark.slow  # suite time (session 70: 15-260 s on 2 cores)
def test_both_inputs_are_refined_and_the_validation_samples_choose(tmp_path):
    rec = _record(tmp_path)
    pinned = dict(model="cascade", grid=SMALL, max_steps=5, orientation="rises", thermal_start="steady", refit=False)
    model, doc, (train, val, yhat) = fit_record(rec, **pinned)
    choice = doc["settings"]["input_choice"]
    runs = choice["runs"]
    assert {r["sees"] for r in runs} == {"voltage", "heat"} and len(runs) == 4  # each input with its rule and fitted memory
    # each input's best run on validation; the other input replaces the screened one only when it is lower there and
    # no higher on training
    screened, other = (min((r for r in runs if (r["sees"] == choice["screened"]) == keep), key=lambda r: r["validation_rmse"])
                       for keep in (True, False))  # fmt: skip
    switch = other["validation_rmse"] < screened["validation_rmse"] and other["train_rmse"] <= screened["train_rmse"]
    best = other if switch else screened
    assert choice["chosen"] == best["sees"] == model.sees and doc["settings"]["memory_used"] == best["memory"]
    assert all(np.isfinite(r["train_rmse"]) and r["train_rmse"] > 0 for r in runs)
    # the kept split fit is the one with that validation RMSE, and the note names every run and the choice
    assert np.sqrt(np.mean((yhat[val] - rec.y[val]) ** 2)) == pytest.approx(best["validation_rmse"], rel=1e-9)
    note = next(n for n in doc["notes"] if n.startswith("hysteresis input and operator memory at t = 0"))
    assert f"-> {best['sees']} {best['memory']};" in note and note.count("validation RMSE") == 4
    # the memory spread compares the two memories of the chosen input only
    spread = doc["settings"]["memory_spread"]
    assert spread is None or sorted(spread["models"]) == sorted(r["memory"] for r in runs if r["sees"] == best["sees"])


def test_a_pinned_input_is_not_compared(tmp_path):
    rec = _record(tmp_path)
    model, doc, _ = fit_record(
        rec, model="cascade", grid=SMALL, max_steps=0, orientation="rises", thermal_start="steady", refit=False, sees="heat"
    )
    assert doc["settings"]["input_choice"] is None and model.sees == "heat"
    assert not any(n.startswith("hysteresis input and") for n in doc["notes"])
