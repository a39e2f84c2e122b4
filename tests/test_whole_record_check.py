"""`--model auto` checks the kept class's whole-record refit against the record (`_report_fit._whole_record_check`):
above `WHOLE_RECORD_CHECK` noise SDs the other classes are refitted too, and one that fits the whole record more than
`WHOLE_RECORD_MARGIN` times better replaces the validation block's choice; below it nothing else is refitted."""

from __future__ import annotations

import numpy as np
import pytest

from smafl_jax.report import _report_fit  # private: choose_structure with stand-in candidates


@pytest.fixture(scope="module")
def record(stand_in_record):
    return stand_in_record


def _stand_ins(record, val, whole, noise_sd=0.01):
    """`fit_one` stand-ins: fixed validation RMSEs (the split fits) and whole-record RMSEs (their refits)."""
    model = _report_fit.build_model("cascade", record)
    calls = {name: 0 for name in val}

    def fit_one(name, options):
        m = {"validation": {"rmse": val[name], "e_r_percent": 10 * val[name]}, "train": {"rmse": val[name] / 2}}

        def finish():
            calls[name] += 1
            noise = {"sd": noise_sd, "whole_record_ratio": None if whole[name] is None else whole[name] / noise_sd}
            # None: a refit whose output is not finite (fit_record then stores no whole-record metrics)
            metrics = {**m, "whole_record": None if whole[name] is None else {"rmse": whole[name]}, "noise": noise}
            doc = {"settings": {"structure": name}, "notes": [f"refit of {name}"], "metrics": metrics, "data": {}}
            return model, doc, (np.ones(len(record), bool), np.zeros(len(record), bool), None)

        return _report_fit.Candidate(model, m, None, finish, None)

    return fit_one, calls


def _choose(record, monkeypatch, val, whole, threads=1):
    # one thread: no early refit, every finish() is the check's; two: the check's refits run side by side
    monkeypatch.setattr(_report_fit, "candidate_threads", lambda k: min(k, threads))
    fit_one, calls = _stand_ins(record, val, whole)
    _, doc, _ = _report_fit.choose_structure(record, fit_one, {}, progress=False)
    return doc, calls


VAL = {"auto": 0.1, "cascade-preisach-gauss": 0.2, "cascade-phase": 0.3}  # the validation block keeps the EUPI cascade


@pytest.mark.parametrize("threads", [1, 2])
def test_a_class_that_cannot_fit_its_record_is_replaced(record, monkeypatch, threads):
    # the kept cascade's whole-record refit stays at 30x the noise; the phase class fits the record at 2x
    whole = {"auto": 0.3, "cascade-preisach-gauss": 0.25, "cascade-phase": 0.02}
    doc, calls = _choose(record, monkeypatch, VAL, whole, threads)
    choice = doc["settings"]["structure_choice"]
    assert choice["chosen"] == "cascade-phase" and doc["settings"]["structure"] == "cascade-phase"
    check = choice["whole_record_check"]
    assert check["switched"] and check["validation_choice"] == "cascade"
    assert check["whole_record_rmse"] == {"cascade": 0.3, "cascade-preisach-gauss": 0.25, "cascade-phase": 0.02}
    assert calls == {"auto": 1, "cascade-preisach-gauss": 1, "cascade-phase": 1}  # each refitted once
    assert "refit of cascade-phase" in doc["notes"] and "whole-record check" in doc["notes"][0]


def test_no_class_far_enough_ahead_keeps_the_choice(record, monkeypatch):
    # every class above the noise, none more than 2x below the kept one: the validation block's choice stays
    doc, calls = _choose(record, monkeypatch, VAL, {"auto": 0.3, "cascade-preisach-gauss": 0.2, "cascade-phase": 0.16})
    choice = doc["settings"]["structure_choice"]
    assert choice["chosen"] == "cascade" and doc["settings"]["structure"] == "auto"
    assert not choice["whole_record_check"]["switched"]
    assert calls == {"auto": 1, "cascade-preisach-gauss": 1, "cascade-phase": 1}


def test_a_refit_near_the_noise_is_not_checked(record, monkeypatch):
    # 1.5x the noise: below the check's threshold, so no other class is refitted (the fit costs what it did)
    doc, calls = _choose(record, monkeypatch, VAL, {"auto": 0.015, "cascade-preisach-gauss": 0.001, "cascade-phase": 0.001})
    choice = doc["settings"]["structure_choice"]
    assert choice["chosen"] == "cascade" and "whole_record_check" not in choice
    assert calls == {"auto": 1, "cascade-preisach-gauss": 0, "cascade-phase": 0}


def test_a_refit_without_finite_output_cannot_win(record, monkeypatch):
    doc, calls = _choose(record, monkeypatch, VAL, {"auto": 0.3, "cascade-preisach-gauss": None, "cascade-phase": 0.2})
    check = doc["settings"]["structure_choice"]["whole_record_check"]
    assert not check["switched"] and check["whole_record_rmse"]["cascade-preisach-gauss"] is None
