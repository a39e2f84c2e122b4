"""Early stopping of the split fit's joint refinement on the validation samples (`report._report_fit._lm_chunks`)."""

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.identify import default_trainable
from smafl_jax.report import _report_fit  # private: the chunked refinement and its constants under test


@pytest.fixture(scope="module")
def record(short_indep_record):
    return short_indep_record


def test_keeps_the_iterate_with_the_lowest_look_and_stops_after_patience(record, monkeypatch):
    monkeypatch.setattr(_report_fit, "LM_CHUNK", 2)
    model = sj.fit(sj.EUPI.from_range(0.0, float(record.u.max())), record, solver=None).model
    spec = default_trainable(model)
    values = iter([1.0, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.4])  # the start, then one per chunk
    seen = []

    def look(m):
        seen.append(m)
        return next(values)

    w = [np.ones(len(record))]
    res, kept, run, looks = _report_fit._lm_chunks(model, spec, record, w, "lm", 40, 1.0, False, look=look)
    if res.converged and run <= 2:
        pytest.skip("the LM converged within one chunk: nothing to stop early")
    assert kept == 2 and res.n_steps == 2
    assert run == 2 * (1 + _report_fit.LM_PATIENCE) and [s for s, _ in looks] == [2, 4, 6]
    assert res.model is seen[1]  # the looked-at model (gain prior applied) of the best chunk is returned


def test_a_refinement_that_never_helps_validation_is_rejected(record, monkeypatch):
    """The start competes as 0 steps: when no chunk lowers the look, the screened start is kept (``rejected``)."""
    monkeypatch.setattr(_report_fit, "LM_CHUNK", 2)
    model = sj.fit(sj.EUPI.from_range(0.0, float(record.u.max())), record, solver=None).model
    n = len(record)
    tr, va = np.arange(n) < 0.7 * n, np.arange(n) >= 0.7 * n
    start_val = [None]
    real = _report_fit._lm_chunks

    def worse_after_start(m, spec, rec, weights, solver, total, gp, progress, look=None):
        def look_worse(x):
            v = look(x)
            if start_val[0] is None:
                start_val[0] = v
                return v
            return v + 1.0  # every refined iterate looks worse than the start

        return real(m, spec, rec, weights, solver, total, gp, progress, look=look_worse)

    monkeypatch.setattr(_report_fit, "_lm_chunks", worse_after_start)
    res, y0, refinement, note = _report_fit._refine_early_stopped(
        model, default_trainable(model), record, tr, va, "lm", 20, None, False
    )
    assert refinement == "rejected" and "raised the validation RMSE" in note
    np.testing.assert_allclose(y0, np.asarray(sj.simulate(model, record.u, record.dt)))


@pytest.mark.slow  # suite time (55 s, one CLI cascade fit): an opt-in flag; the in-process early-stopping tests above stay in the default suite
def test_cli_flag_reaches_the_fit_and_is_recorded(record, tmp_path):
    """`smafl fit --early-stopping`: fit.json says so and carries the chunks' validation errors.  Without the flag
    there is no early-stopping entry: tests/test_fit.py::test_cli_fit_writes_fit_json_and_simulate_accepts_it checks
    that on its own CLI fit (a second cascade fit here cost the suite ~45 s)."""
    import json

    from smafl_jax.cli import main as cli_main

    common = ["fit", str(record.path), "--model", "cascade", "--max-steps", "100", "--no-figures", "--no-refit"]
    assert cli_main([*common, "--early-stopping", "--out", str(tmp_path / "es")]) == 0
    doc = json.loads((tmp_path / "es" / "fit.json").read_text())
    assert doc["settings"]["early_stopping"] is True
    es = doc["solver"]["early_stopping"]
    assert 0 < es["steps_run"] <= 100 and es["steps_kept"] <= es["steps_run"]
    assert [s for s, _ in es["validation_mse"]][-1] == es["steps_run"]
