"""`--model auto` says when its class choice rests on extrapolation: for every candidate, fewer than 90 % of the
validation samples lie on branches its training part visits (`Candidate.coverage` below the coverage warning level)."""

from __future__ import annotations

import pytest

from smafl_jax.report import _report_fit  # private: choose_structure with stand-in candidates


@pytest.fixture(scope="module")
def record(stand_in_record):
    return stand_in_record


def _candidates(record, coverage):
    """`fit_one` stand-in: fixed validation RMSEs (the Preisach cascade lowest) and the given coverages."""
    model = _report_fit.build_model("cascade", record)
    rmse = {"auto": 0.3, "cascade-preisach": 0.1, "cascade-preisach-gauss": 0.2}

    def fit_one(name, options):
        m = {"validation": {"rmse": rmse[name], "e_r_percent": 10 * rmse[name]}, "train": {"rmse": rmse[name] / 2}}
        doc = {"settings": {"structure": name}, "notes": [], "metrics": m}
        return _report_fit.Candidate(model, m, None, lambda: (model, doc, None), coverage[name])

    return fit_one


@pytest.mark.parametrize(
    ("coverage", "flagged"),
    [
        ({"auto": 0.04, "cascade-preisach": 0.3, "cascade-preisach-gauss": 0.12}, True),
        ({"auto": 0.95, "cascade-preisach": 0.3, "cascade-preisach-gauss": 0.12}, False),  # one class was judged fairly
        ({"auto": None, "cascade-preisach": 0.3, "cascade-preisach-gauss": 0.12}, False),  # not measured: say nothing
    ],
)
def test_a_choice_made_on_extrapolation_says_so(record, monkeypatch, coverage, flagged):
    monkeypatch.setattr(_report_fit, "candidate_threads", lambda k: 1)
    _, doc, _ = _report_fit.choose_structure(record, _candidates(record, coverage), {}, progress=False)
    choice = doc["settings"]["structure_choice"]
    assert choice["chosen"] == "cascade-preisach"  # the rule itself is unchanged
    assert [c["validation_coverage"] for c in choice["candidates"]] == list(coverage.values())
    assert choice.get("extrapolating", False) is flagged
    assert ("uncertain" in choice["on"]) is flagged and ("uncertain" in doc["notes"][0]) is flagged
    if flagged:
        assert "4-30 %" in choice["on"] and "--model cascade" in choice["on"]
