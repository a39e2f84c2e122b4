"""Library workflows: `sample_posterior` is the `smafl sample` workflow as a function (same results as the
CLI, atomic outputs, resume / refusal of a chain of other settings, errors naming the settings)."""

import json
import logging
import os
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.workflows.sample import FILES
from tests.reference import random_reversals

FAST = {"steps": 20, "walkers": 8, "draws": 10, "progress": False}


@pytest.fixture(scope="module")
def problem(tmp_path_factory):
    """A short cascade record (CSV) and a fit.json of its model (gains by least squares at the true k1)."""
    tmp = tmp_path_factory.mktemp("wf")
    rng = np.random.default_rng(3)
    base = sj.Cascade.from_range(7.4, n_sym=2, n_alpha=1, n_asym=2, poly_order=2)
    hyst = base.hysteresis.with_linear_weights(np.array([0.3, 1.0, 0.5, 0.2, 0.1, 0.05, 0.2]))
    truth = sj.Cascade(thermal=sj.JouleThermal(k1=jnp.asarray(0.2), k2=jnp.asarray(0.05)), hysteresis=hyst)
    u = random_reversals(rng, 160)
    y = np.asarray(truth.simulate(u, 0.5)) + 0.02 * rng.standard_normal(len(u))
    csv = tmp / "rec.csv"
    sj.atomic_write_csv(csv, {"time_s": 0.5 * np.arange(len(u)), "voltage_V": u, "displacement_mm": y})
    rec = sj.load_record(csv)
    fitted = sj.init_linear(truth, rec)
    fit_json = tmp / "fit.json"
    data = {"file": csv.name, "input_column": "voltage_V", "output_column": "displacement_mm", "sample_time_s": rec.dt}
    sj.save_model(fit_json, fitted, data=data)
    return csv, fit_json, rec


@pytest.mark.slow  # suite time (10-minute budget): 17 s; `smafl sample` from the CLI runs in test_bayes.py, the library's sampling below
def test_library_and_cli_write_the_same_results(problem, tmp_path, capsys):
    from smafl_jax.cli import main

    csv, fit_json, _ = problem
    argv = ["sample", str(csv), "--fit", str(fit_json), "--out", str(tmp_path / "cli"), "--no-progress"]
    argv += ["--steps", "20", "--walkers", "8", "--draws", "10"]
    assert main(argv) == 0
    cli_stdout = capsys.readouterr().out
    res = sj.sample_posterior(str(csv), str(fit_json), out=tmp_path / "lib", **FAST)
    assert capsys.readouterr().out == ""  # the library prints nothing on stdout
    assert isinstance(res, sj.SamplingResult) and res.out == tmp_path / "lib"
    cli = json.loads((tmp_path / "cli" / "summary.json").read_text())
    assert json.loads((tmp_path / "lib" / "summary.json").read_text()) == cli == json.loads(json.dumps(res.summary))
    assert sorted(os.listdir(tmp_path / "cli")) == sorted(os.listdir(tmp_path / "lib"))
    for name in ("parameters.csv", "predictive.csv", "run.json"):
        assert (tmp_path / "cli" / name).read_bytes() == (tmp_path / "lib" / name).read_bytes(), name
    # the CLI's console lines are made from the returned summary
    assert f"{cli['n_steps']} steps x {cli['n_walkers']} walkers, burn-in {cli['burn']}" in cli_stdout
    assert set(res.summary["parameters"]) == {"thermal.k1", "noise.sigma"} == set(res.posterior.names)
    assert res.run.chain.shape == (20, 8, 2)


def test_outputs_are_written_atomically_and_listed(problem, tmp_path, monkeypatch, caplog):
    csv, fit_json, rec = problem
    replaced = []
    real_replace = os.replace

    def recording_replace(src, dst):
        replaced.append((Path(src), Path(dst)))
        return real_replace(src, dst)

    monkeypatch.setattr(os, "replace", recording_replace)
    out = tmp_path / "out"
    with caplog.at_level(logging.INFO, logger="smafl_jax.workflows.sample"):
        res = sj.sample_posterior(rec, sj.load_model(fit_json), out=out, **FAST)  # Python objects, not files
    assert "sampling 2 parameters" in caplog.text
    assert set(res.files) == set(FILES) and all(p.parent == out and p.stat().st_size > 0 for p in res.files.values())
    # every result but emcee's own chain file went through a temporary file in the same folder and os.replace
    atomic = {dst.name for src, dst in replaced if src.parent == dst.parent == out and src.name.startswith(".")}
    assert set(FILES) - {"chain.h5"} <= atomic
    assert not [p for p in os.listdir(out) if p.endswith(".tmp")]
    assert res.summary["fit"] is None and res.summary["data"]["file"] == csv.name
    assert res.summary["data"]["heldout"] == f"last {len(rec) - res.summary['data']['n_train']} samples"
    assert json.loads((out / "summary.json").read_text()) == json.loads(json.dumps(res.summary))


@pytest.mark.slow  # suite time (10-minute budget): 12 s; resuming and refusing other settings run through the CLI in test_bayes.py
def test_resume_extends_and_other_settings_are_refused_unless_restart(problem, tmp_path):
    csv, fit_json, _ = problem
    out = tmp_path / "out"
    sj.sample_posterior(csv, fit_json, out=out, **FAST)
    run_json = (out / "run.json").read_bytes()
    longer = sj.sample_posterior(csv, fit_json, out=out, **{**FAST, "steps": 30})
    assert longer.run.resumed_from == 20 and longer.summary["n_steps"] == 30
    with pytest.raises(sj.UserInputError, match=r"other data or settings .* pass restart=True"):
        sj.sample_posterior(csv, fit_json, out=out, noise="student-t", **FAST)
    assert (out / "run.json").read_bytes() == run_json  # the refused run left the earlier results alone
    fresh = sj.sample_posterior(csv, fit_json, out=out, noise="student-t", restart=True, **FAST)
    assert fresh.run.resumed_from == 0 and fresh.summary["n_steps"] == 20
    assert json.loads((out / "run.json").read_text())["linear"] == "profile"  # auto: Student-t noise profiles the gains


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"steps": 5}, r"steps must be >= 10, got 5"),
        ({"burn": 20}, r"burn must be in \[0, steps\)"),
        ({"holdout_fraction": 0.95}, r"holdout_fraction must be in"),
        ({"linear": "exact"}, r"linear must be 'auto' or one of"),
        ({"walkers": 2}, r"need at least 2 x 2 = 4 walkers"),
    ],
)
def test_bad_settings_raise_user_input_errors_before_writing(problem, tmp_path, kwargs, match):
    csv, fit_json, _ = problem
    with pytest.raises(sj.UserInputError, match=match):
        sj.sample_posterior(csv, fit_json, out=tmp_path / "out", **{**FAST, **kwargs})
    assert not (tmp_path / "out").exists()


def test_a_record_object_with_column_names_is_refused(problem, tmp_path):
    _, fit_json, rec = problem
    with pytest.raises(sj.UserInputError, match="has its columns already"):
        sj.sample_posterior(rec, fit_json, out=tmp_path / "out", input="voltage_V", **FAST)


def test_a_heldout_band_wider_than_the_noise_is_reported(problem, tmp_path):
    """The unconstrained-band rule of `sample_posterior` (`BAND_WARN` noise SDs on more than a tenth of the held-out
    samples): a band of 10 noise SDs on the held-out half is reported with its first time and size, 2 SDs is not."""
    from smafl_jax.workflows.sample import BAND_WARN, _sampled_branches, _unconstrained  # private: the rule itself

    _, fit_json, rec = problem
    n = len(rec) // 2
    post = sj.Posterior(sj.load_model(fit_json), (rec.u[:n], rec.y[:n]), rec.dt, linear="marginalise")
    mask = np.arange(len(rec)) < n
    sampled = _sampled_branches(post, [rec], [n])
    sigma = 0.02
    for width, expected in ((10.0, True), (2.0, False)):
        band = np.where(mask, 0.5, width) * sigma
        fq = np.stack([-band / 2, np.zeros(len(rec)), band / 2])
        got = _unconstrained(post, rec, 0, mask, fq, sigma, sampled)
        assert (got is not None) == expected == (width > BAND_WARN)
        if expected:
            assert f"on {len(rec) - n} of {len(rec) - n} held-out samples (from {rec.time[n]:.4g} s)" in got
            assert f"up to {width * sigma:.3g}" in got


def test_a_fit_that_validated_far_above_the_noise_warns_that_bands_may_be_narrow():
    """`STRUCTURE_WARN`: the sampler's bands are conditional on the fitted structure; a fit whose own validation erred
    above that many noise SDs gets the warning, one below it, or a document without the ratio (a model object), not."""
    from smafl_jax.workflows.sample import STRUCTURE_WARN, _structure_warning  # private: the rule itself

    def doc(ratio):
        return {"metrics": {"noise": {"validation_ratio": ratio}}}

    got = _structure_warning(doc(2.5 * STRUCTURE_WARN))
    assert got is not None and f"{2.5 * STRUCTURE_WARN:.3g}x the noise" in got and "too narrow" in got
    for quiet in (doc(0.9 * STRUCTURE_WARN), doc(None), doc(float("nan")), {}, {"metrics": None}):
        assert _structure_warning(quiet) is None
