"""`--model auto` fits its candidate classes on several threads: same results as one after another, errors and
progress lines that stay attributable."""

from __future__ import annotations

import logging
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax import _progress  # private: the thread-aware step counters and line tags under test
from smafl_jax.identify import _choose  # private: the thread-safe screening memo under test
from smafl_jax.report import (
    HYSTERESIS,
    _report_fit,  # private: the candidate pool under test
    fit_record,
)

sys.path.insert(0, str(Path(__file__).resolve().parent))
import indep_direct

SMALL = dict(n_sym=4, n_alpha=2, n_asym=2, poly_order=3)


def _voltage_record(tmp_path, seed, n, dt):
    r = indep_direct.make_record(seed, "preisach", "steps", n=n, dt=dt, u_lo=0.2, u_span=6.0)
    path = tmp_path / f"v{seed}.csv"
    np.savetxt(path, np.column_stack([r["t"], r["u"], r["y"]]), delimiter=",", header="time_s,voltage_V,displacement_mm",
               comments="", fmt="%.9g")  # fmt: skip
    return sj.load_record(path)


def _without_seconds(doc):
    choice = doc["settings"]["structure_choice"]
    return [{k: v for k, v in c.items() if k != "seconds"} for c in choice["candidates"]], choice["chosen"]


@pytest.mark.slow  # suite time (18 s, two auto fits); overlap, order, errors and per-thread progress stay by default
def test_threads_give_the_results_of_one_after_another(tmp_path, monkeypatch):
    # a quasi-static drive record (10 s per sample): the static classes join after the first candidate, on the pool too
    rec = _voltage_record(tmp_path, 5, 300, 10.0)
    pinned = dict(max_steps=0, grid=SMALL, orientation="rises", sees="voltage", thermal_start="steady", memory="descended")
    got = {}
    for n in (1, 3):
        monkeypatch.setattr(_report_fit, "candidate_threads", lambda k, n=n: min(k, n))
        model, doc, _ = fit_record(rec, **pinned)
        assert doc["settings"]["structure_choice"]["threads"] == n
        got[n] = (sj.model_to_dict(model), _without_seconds(doc), doc["metrics"], doc["notes"])
    cascades = 1 + sum(sj.models.hysteresis_class(k).compared_behind_lag for k in HYSTERESIS if k != "eupi")
    assert len(got[1][1][0]) == cascades + len(HYSTERESIS)  # the cascades auto compares, then every static class
    assert got[3] == got[1]


def _fake_candidates(record, log, barrier, fail=None):
    """`fit_one` stand-in: records when each candidate starts; the first two must overlap (barrier)."""
    model = _report_fit.build_model("cascade", record)
    rmse = {"auto": 0.3, "cascade-preisach": 0.4, "cascade-preisach-gauss": 0.2, "cascade-phase": 0.1}

    def fit_one(name, options):
        log.append((name, threading.current_thread().name))
        if name in ("auto", "cascade-preisach-gauss"):
            barrier.wait(timeout=20)  # both at once, or BrokenBarrierError
        if name == fail:
            raise ValueError(f"{name} failed")
        m = {"validation": {"rmse": rmse[name], "e_r_percent": 10 * rmse[name]}, "train": {"rmse": rmse[name] / 2}}
        doc = {"settings": {"structure": name}, "notes": [], "metrics": m}
        return _report_fit.Candidate(model, m, None, lambda: (model, doc, None))

    return fit_one


def test_candidates_overlap_and_keep_their_order(tmp_path, monkeypatch):
    rec = _voltage_record(tmp_path, 6, 400, 0.05)  # fast sampling: no static classes
    monkeypatch.setattr(_report_fit, "candidate_threads", lambda k: min(k, 2))
    # the free Preisach (no joint refinement) back among the classes behind the lag, so that one candidate has none
    monkeypatch.setattr(sj.Preisach, "compared_behind_lag", True)
    log = []
    _, doc, _ = _report_fit.choose_structure(rec, _fake_candidates(rec, log, threading.Barrier(2)), {}, progress=False)
    choice = doc["settings"]["structure_choice"]
    # the default cascade and the first class with a joint refinement start together; the Preisach (no refinement) last
    assert [n for n, _ in log][:2] in (["auto", "cascade-preisach-gauss"], ["cascade-preisach-gauss", "auto"])
    assert [n for n, _ in log][2:] == ["cascade-phase", "cascade-preisach"]
    assert all(t.startswith("smafl-candidate") for _, t in log)
    order = ["cascade", "cascade-preisach", "cascade-preisach-gauss", "cascade-phase"]  # the registry's order
    assert [c["structure"] for c in choice["candidates"]] == order
    assert choice["chosen"] == "cascade-phase" and choice["threads"] == 2


def test_a_failing_candidate_raises_its_error(tmp_path, monkeypatch):
    rec = _voltage_record(tmp_path, 6, 400, 0.05)
    monkeypatch.setattr(_report_fit, "candidate_threads", lambda k: min(k, 2))
    log = []
    with pytest.raises(ValueError, match="cascade-preisach-gauss failed"):
        _report_fit.choose_structure(
            rec, _fake_candidates(rec, log, threading.Barrier(2), fail="cascade-preisach-gauss"), {}, progress=False
        )
    assert not any(t.name.startswith("smafl-candidate") for t in threading.enumerate())  # nothing left running
    # one thread: the error is raised where it happens, nothing after it runs
    monkeypatch.setattr(_report_fit, "candidate_threads", lambda k: 1)
    log1 = []
    with pytest.raises(ValueError, match="auto failed"):
        _report_fit.choose_structure(rec, _fake_candidates(rec, log1, threading.Barrier(1), fail="auto"), {}, progress=False)
    assert [n for n, _ in log1] == ["auto"]


def test_a_screening_in_progress_is_waited_for_not_repeated():
    memo = _choose._Screenings()
    calls, out = [], {}
    gate = threading.Event()

    def make():
        calls.append(1)
        gate.wait(5)
        return [np.arange(3.0)], [{"row": 1}]

    def run(i):
        out[i] = memo.get_or_make("k", make)

    threads = [threading.Thread(target=run, args=(i,)) for i in range(3)]
    for t in threads:
        t.start()
    time.sleep(0.2)
    gate.set()
    for t in threads:
        t.join(10)
    assert len(calls) == 1
    assert sorted(r for _, r in out.values()) == [False, True, True]
    assert all(np.array_equal(v[0][0][0], np.arange(3.0)) for v in out.values())
    assert len({id(v[0][1][0]) for v in out.values()}) == 3  # each caller has its own copy

    def broken():
        raise RuntimeError("no screening")

    with pytest.raises(RuntimeError, match="no screening"):
        memo.get_or_make("bad", broken)
    with pytest.raises(RuntimeError, match="no screening"):  # a later caller of that key gets the same failure
        memo.get_or_make("bad", make)


def test_step_counts_and_lines_stay_with_their_thread(caplog):
    counts, ready = {}, threading.Barrier(2)

    def run(tag, n):
        with _progress.tagged(tag), _progress.heartbeat(tag, max_steps=50, every_s=60) as counter:
            ready.wait(5)  # both heartbeats open: a step must reach the counter of its own thread
            for _ in range(n):
                _progress.count_step()
            ready.wait(5)
            _progress.say(f"{tag} done")
            counts[tag] = counter.n

    with caplog.at_level(logging.INFO, logger="smafl_jax.progress"):
        threads = [threading.Thread(target=run, args=(t, n)) for t, n in (("a", 3), ("b", 7))]
        for t in threads:
            t.start()
        for t in threads:
            t.join(10)
    assert counts == {"a": 3, "b": 7}
    lines = [r.getMessage() for r in caplog.records]
    assert "[a] a done" in lines and "[b] b done" in lines
    _progress.say("untagged")
    assert not _progress._TAGS  # nothing left behind


@pytest.mark.slow  # suite time (session 70: 15-260 s on 2 cores)
def test_a_rejected_refinement_refits_on_a_side_thread_with_the_same_result(tmp_path, monkeypatch):
    """The default class's whole-record refit of a refinement rejected on validation starts before the split fit's
    polish, on a thread of its own (`_fit_structure(early_refit=True)`); the refit is the one made after it."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import indep_plant

    r = indep_plant.make_record(3, drive="multisine", rate_hz=10, minutes=3.0, start="cold")
    path = tmp_path / "rec.csv"
    indep_plant.write_csv(path, r)
    rec = sj.load_record(path)
    monkeypatch.setattr(_report_fit, "candidate_threads", lambda k: min(k, 2))
    side = []
    on_side = _report_fit._on_side_thread
    monkeypatch.setattr(_report_fit, "_on_side_thread", lambda fn, *a: side.append(fn) or on_side(fn, *a))
    opts = dict(model="auto", defer_refit=True, grid=SMALL, thresholds=True, tilts=True)
    got = {}
    for early in (False, True):
        cand = _report_fit._fit_structure(rec, early_refit=early, **opts)
        assert (cand.pending is not None) == early
        model, doc, _ = cand.finish()
        assert doc["solver"]["refinement"] == "rejected"  # the case the side thread is for
        got[early] = (sj.model_to_dict(model), doc["metrics"], doc["notes"])
    assert len(side) == 1
    assert got[True] == got[False]


def test_choose_structure_waits_for_a_side_refit_of_a_class_it_does_not_keep(tmp_path, monkeypatch):
    rec = _voltage_record(tmp_path, 6, 400, 0.05)
    monkeypatch.setattr(_report_fit, "candidate_threads", lambda k: min(k, 2))
    fit_one = _fake_candidates(rec, [], threading.Barrier(2))
    ended = threading.Event()

    def slow_refit():
        time.sleep(0.5)
        ended.set()

    def with_pending(name, options):
        cand = fit_one(name, options)
        if name != "auto":
            return cand
        pending = _report_fit._on_side_thread(slow_refit)
        return cand._replace(pending=pending)

    _, doc, _ = _report_fit.choose_structure(rec, with_pending, {}, progress=False)
    assert doc["settings"]["structure_choice"]["chosen"] == "cascade-phase"  # the default class is not kept
    assert ended.is_set()  # and its side refit had ended before the choice returned
