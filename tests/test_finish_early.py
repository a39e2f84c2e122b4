"""`--model auto` on two threads starts the whole-record refit of the best candidate so far once a thread goes idle
(`_report_fit._finish_best_when_idle`): the result is the one of a refit after the choice, each candidate's ``finish()``
runs at most once, and a candidate that overtakes at the end is refitted itself."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from smafl_jax.report import _report_fit  # private: choose_structure with stand-in candidates


@pytest.fixture(scope="module")
def record(stand_in_record):
    return stand_in_record


def _stand_ins(record, rmse):
    """`fit_one` stand-ins with fixed validation RMSEs; the phase cascade (submitted last, fitted alone on two
    threads) returns only once a refit has started on the idle thread (or after 20 s, when none does)."""
    model = _report_fit.build_model("cascade", record)
    calls = {name: 0 for name in rmse}
    started = threading.Event()

    def fit_one(name, options):
        if name == "cascade-phase":
            started.wait(timeout=20.0)
        m = {"validation": {"rmse": rmse[name], "e_r_percent": 10 * rmse[name]}, "train": {"rmse": rmse[name] / 2}}

        def finish():
            calls[name] += 1
            started.set()
            doc = {"settings": {"structure": name}, "notes": [f"refit of {name}"], "metrics": m, "data": {}}
            return model, doc, (np.ones(len(record), bool), np.zeros(len(record), bool), None)

        return _report_fit.Candidate(model, m, None, finish, None)

    return fit_one, calls, started


@pytest.mark.parametrize(
    ("rmse", "kept", "median"),
    [
        ({"auto": 0.1, "cascade-preisach-gauss": 0.2, "cascade-phase": 0.3}, "auto", False),  # the early refit is used
        ({"auto": 0.2, "cascade-preisach-gauss": 0.3, "cascade-phase": 0.1}, "cascade-phase", False),  # overtaken
        ({"auto": 0.2, "cascade-preisach-gauss": 0.3, "cascade-phase": 0.1}, "cascade-phase", True),  # --median
    ],
)
def test_best_so_far_refitted_on_the_idle_thread(record, monkeypatch, rmse, kept, median):
    monkeypatch.setattr(_report_fit, "candidate_threads", lambda k: 2)
    fit_one, calls, started = _stand_ins(record, rmse)
    _, doc, _ = _report_fit.choose_structure(record, fit_one, {}, progress=False, median=median)
    assert started.is_set()  # a refit started while the phase candidate was still being fitted
    choice = doc["settings"]["structure_choice"]
    assert choice["chosen"] == ("cascade" if kept == "auto" else kept)
    assert doc["settings"]["structure"] == kept and f"refit of {kept}" in doc["notes"]
    assert calls["auto"] == 1  # the best so far when a thread went idle: refitted early, once
    assert calls[kept] == 1 and calls["cascade-preisach-gauss"] == (1 if median else 0)  # --median refits every class
    assert sum(calls.values()) == (1 if kept == "auto" else 2) + median
    if median:
        assert doc["median"]["members"] == ["cascade", "cascade-preisach-gauss", "cascade-phase"]


def test_one_thread_refits_only_the_kept_candidate(record, monkeypatch):
    monkeypatch.setattr(_report_fit, "candidate_threads", lambda k: 1)
    fit_one, calls, started = _stand_ins(record, {"auto": 0.2, "cascade-preisach-gauss": 0.1, "cascade-phase": 0.3})
    started.set()  # nothing waits for an early refit: one thread fits the candidates one after another
    _, doc, _ = _report_fit.choose_structure(record, fit_one, {}, progress=False)
    assert doc["settings"]["structure_choice"]["chosen"] == "cascade-preisach-gauss"
    assert calls == {"auto": 0, "cascade-preisach-gauss": 1, "cascade-phase": 0}
