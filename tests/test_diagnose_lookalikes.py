"""Issue 13: effects that explain a residual alike are reported as ambiguous when they are lookalikes (one group of
`AbstractEffect.lookalikes`), and none is selected when they share no group (a misfit of the base model)."""

from __future__ import annotations

import pytest

from smafl_jax.diagnosis import (
    _diagnose,  # private: the selection step with stand-in gates
    lookalike_groups,
)
from smafl_jax.effects import EFFECTS


def test_every_registered_effect_declares_its_lookalike_groups():
    for name, cls in EFFECTS.items():
        assert cls.lookalikes and all(isinstance(g, str) and g for g in cls.lookalikes), name


@pytest.mark.parametrize(
    ("names", "groups"),
    [
        (["creep", "strain_accumulation"], ("slow",)),
        (["ambient_drift", "creep"], ("slow",)),  # slow drift looks like creep
        (["creep", "output_lag"], ("timing",)),  # creep of the whole output is an output lag
        (["resistance_tc", "nonlinear_cooling", "ambient_drift"], ("thermal",)),
        (["delay", "output_lag", "sensor_lag", "sensor_lead"], ("timing",)),
        (["creep", "asymmetric_cooling", "input_warp"], ()),
        (["rate_dependence", "resistance_tc"], ()),
        (["nonlocal_memory"], ("nonlocal_memory",)),  # a name without groups is its own
        (["nonlocal_memory", "creep"], ()),
    ],
)
def test_lookalike_groups(names, groups):
    assert lookalike_groups(names) == groups


def _select(monkeypatch, heldout):
    """`_select_calibrated` on stand-in candidates that all pass the gates, with the given held-out RMSEs."""
    monkeypatch.setattr(_diagnose, "calibration_gates", lambda *a, **k: {"accepted": True})
    monkeypatch.setattr(_diagnose, "_held", lambda m, split: {"rmse": heldout[m]})
    cands = [{"name": n, "fitted": True, "heldout_rmse": r} for n, r in heldout.items()]
    fitted = {n: (n, r, None) for n, r in heldout.items()}  # the "model" is its name
    cal = {**_diagnose.CALIBRATED_DEFAULTS, "seed": 0}
    out = _diagnose._select_calibrated(
        None, None, "base", {"rmse": 1.0}, cands, fitted, min_gain=0.05, max_effects=1, cal=cal, holdout_residue=2,
        verbose=False,
    )  # fmt: skip
    _diagnose._decisions(cands, out[0], out[2], "calibrated", out[3])
    return out, {c["name"]: c["decision"] for c in cands}


def test_unrelated_effects_alike_select_nothing(monkeypatch):
    (selected, chosen, ambiguous, unspecific), decisions = _select(
        monkeypatch, {"creep": 0.520, "asymmetric_cooling": 0.529, "input_warp": 0.560, "output_lag": 0.62}
    )
    assert selected == [] and chosen == "base" and ambiguous == []
    assert unspecific == ["creep", "asymmetric_cooling", "input_warp"]  # output_lag is 19 % worse: not in the set
    assert decisions["creep"].startswith("passes; not selected") and "share no lookalike group" in decisions["creep"]


def test_lookalikes_alike_stay_an_ambiguous_selection(monkeypatch):
    (selected, chosen, ambiguous, unspecific), _ = _select(
        monkeypatch, {"creep": 0.50, "strain_accumulation": 0.52, "input_warp": 0.7}
    )
    assert selected == ["creep"] and chosen == "creep" and ambiguous == ["creep", "strain_accumulation"] and unspecific == []


def test_a_clear_winner_is_selected_whatever_else_passes(monkeypatch):
    (selected, _, ambiguous, unspecific), _ = _select(monkeypatch, {"output_lag": 0.40, "creep": 0.47, "input_warp": 0.48})
    assert selected == ["output_lag"] and ambiguous == [] and unspecific == []


def test_time_left_counts_only_candidates_that_run_the_calibrated_test(monkeypatch):
    """Candidates below the gain gate are rejected at once, so the estimate of the time left weighs them near zero (it
    said "about 10 min left" one step before the end of a new-user diagnosis that then finished at once)."""
    seen = {}

    class Capture(_diagnose.Steps):
        def __init__(self, label, total, **kw):
            seen[label] = kw.get("weights")
            super().__init__(label, total, **{**kw, "enabled": False})

    monkeypatch.setattr(_diagnose, "Steps", Capture)
    _select(monkeypatch, {"creep": 0.50, "input_warp": 0.90, "output_lag": 0.97, "delay": 0.99})
    assert seen["diagnose: calibrated test"] == [1.0, 1.0, 0.01, 0.01]  # gains 50 %, 10 %, 3 %, 1 % vs min_gain 5 %


def test_a_base_at_the_noise_floor_tests_no_effect(monkeypatch):
    """Issue 13: a base whose held-out RMSE is within `BASE_AT_FLOOR` noise SDs leaves nothing for an effect to explain;
    the calibrated test (folds, null records) is not run and nothing is selected, however much a candidate gains."""

    def never(*a, **k):
        raise AssertionError("the calibrated test ran on a base at the noise floor")

    monkeypatch.setattr(_diagnose, "calibration_gates", never)
    cands = [{"name": "creep", "fitted": True, "heldout_rmse": 0.95}]
    cal = {**_diagnose.CALIBRATED_DEFAULTS, "seed": 0}
    kw = dict(min_gain=0.05, max_effects=1, cal=cal, holdout_residue=2, verbose=False)
    fitted = {"creep": ("creep", 0.95, None)}
    out = _diagnose._select_calibrated(None, None, "base", {"rmse": 1.0}, cands, fitted, noise_sd=1.0 / 1.19, **kw)
    assert out == ([], "base", [], [])
    assert cands[0]["accepted"] is False and "noise floor" in cands[0]["calibration"]["reason"]
    _diagnose._decisions(cands, out[0], out[2], "calibrated", out[3])
    assert cands[0]["decision"].startswith("rejected: the base model's held-out RMSE is 1.19x")
    # above the floor (1.3x) the test runs as before
    monkeypatch.setattr(_diagnose, "calibration_gates", lambda *a, **k: {"accepted": True})
    monkeypatch.setattr(_diagnose, "_held", lambda m, split: {"rmse": 0.95})
    cands = [{"name": "creep", "fitted": True, "heldout_rmse": 0.95}]
    out = _diagnose._select_calibrated(None, None, "base", {"rmse": 1.0}, cands, fitted, noise_sd=1.0 / 1.3, **kw)
    assert out[0] == ["creep"]
