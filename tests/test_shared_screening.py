"""`shared_screening`: classes that screen on the same grid (Preisach, Gaussian Preisach) screen once within it."""

import jax
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.identify import (
    _choose,  # private: counts the screenings made (`_choose._screen`)
    screen_start,
    shared_screening,
)
from smafl_jax.report._report_fit import build_model  # private: the structures `--model auto` fits

KW = {"k1_grid": 6, "sees": "heat", "thermal_start": "steady"}  # one input and one start: few programs to compile


@pytest.fixture(scope="module")
def record(short_indep_record):
    return short_indep_record


def _counting(monkeypatch):
    calls = []
    real = _choose._screen

    def counted(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(_choose, "_screen", counted)
    return calls


def _same(a, b):
    la, ta = jax.tree_util.tree_flatten(a)
    lb, tb = jax.tree_util.tree_flatten(b)
    return ta == tb and all(np.array_equal(np.asarray(x), np.asarray(y)) for x, y in zip(la, lb))


def _rows(table):
    return [{k: v for k, v in row.items() if k != "seconds"} for row in table]


@pytest.mark.slow  # suite time (23 s, three Preisach screenings); the memo key is checked by default below
def test_second_class_on_the_same_grid_reuses_the_screening(record, monkeypatch):
    n = len(record)
    w, v = [np.r_[np.ones(n - 300), np.zeros(300)]], [np.r_[np.zeros(n - 300), np.ones(300)]]
    alone = screen_start(build_model("cascade-preisach-gauss", record), record, w, val_weights=v, **KW)
    calls = _counting(monkeypatch)
    with shared_screening():
        p = screen_start(build_model("cascade-preisach", record), record, w, val_weights=v, **KW)
        g = screen_start(build_model("cascade-preisach-gauss", record), record, w, val_weights=v, **KW)
        assert len(calls) == 1
        # a mutated table from the first call must not reach a later one
        p[1].clear()
        g2 = screen_start(build_model("cascade-preisach-gauss", record), record, w, val_weights=v, **KW)
        assert len(calls) == 1 and _rows(g2[1]) == _rows(alone[1])
        # other training samples are another screening
        w_other = [np.r_[np.ones(n - 400), np.zeros(400)]]
        screen_start(build_model("cascade-preisach-gauss", record), record, w_other, val_weights=v, **KW)
        assert len(calls) == 2
    assert type(p[0].hysteresis) is sj.Preisach and type(g[0].hysteresis) is sj.GaussianPreisach
    assert _same(g[0], alone[0]) and _rows(g[1]) == _rows(alone[1])
    # outside the block nothing is shared
    screen_start(build_model("cascade-preisach-gauss", record), record, w, val_weights=v, **KW)
    assert len(calls) == 3


def test_key_changes_with_data_and_options(record):
    data = _choose.as_fit_data(record)  # private: the triples screen_start keys on
    m = build_model("cascade-preisach", record)
    ones = [np.ones(len(record))]
    key = _choose._screening_key(m, data, ones, None, ("auto",))  # private: the memo key under test
    assert key == _choose._screening_key(m, _choose.as_fit_data(record), [np.ones(len(record))], None, ("auto",))
    y = data[0][1].copy()
    y[-1] += 1e-12
    assert key != _choose._screening_key(m, [(data[0][0], y, data[0][2])], ones, None, ("auto",))
    assert key != _choose._screening_key(m, data, ones, None, ("rises",))
    assert key != _choose._screening_key(m, data, ones, [np.zeros(len(record))], ("auto",))
    assert key != _choose._screening_key(m.with_hysteresis(m.hysteresis.screening_grid()), data, ones, None, ("auto",))
