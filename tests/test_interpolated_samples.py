"""Samples that resampling interpolated across a logger's gaps are not measurements: no fit weight, no score.

`Record.measured` marks them; `split_masks`, the joint fit of several records, the leave-one-record-out scores, the
diagnosis segments and the posterior's likelihood (`Posterior(mask=)`) leave them out, while the model still runs
through them.  Checked by changing only the
interpolated outputs of a record: nothing a fit reports may move.
"""

import dataclasses
import json
from pathlib import Path

import equinox as eqx
import numpy as np
import pytest
from scipy import stats

import smafl_jax as sj
from smafl_jax.data.split import time_block
from smafl_jax.report import fit_record
from tests.reference import play_loop as reference_play
from tests.test_bayes import _small_cascade_problem

# initialiser only (bounded least squares for the gains): what enters the loss is under test, not the refinement
FAST = dict(model="eupi", max_steps=0, grid=dict(n_sym=6, n_alpha=0, n_asym=0, poly_order=2))


def play_loop(u, r):
    """Symmetric play operator (PAPER.md eq. 1, alpha = 1) started as if the input came down from above."""
    return reference_play(u, r, 1.0, u[0] + r)[:, 0]


def _bursty_csv(path, seed, n_bursts=40, burst=8, missing=4, dt=0.1):
    """A logger writing bursts of ``burst`` samples on a ``dt`` grid with ``missing`` grid points lost between them;
    output: a hysteretic plant (plain numpy) plus noise."""
    rng = np.random.default_rng(seed)
    k = np.concatenate([b * (burst + missing) + np.arange(burst) for b in range(n_bursts)])
    t = k * dt
    u = 2.5 + 1.8 * np.sin(2 * np.pi * t / 7.0) * np.interp(t, [0, t[-1]], [1.0, 0.6])
    y = 0.2 * u + 0.6 * play_loop(u, 0.8) + 0.3 * play_loop(u, 1.6) + 0.002 * rng.standard_normal(t.size)
    sj.atomic_write_csv(path, {"time_s": t, "voltage_V": u, "displacement_mm": y})
    return path, t


def _corrupt(rec, size=5.0):
    """``rec`` with every interpolated output moved by ``size`` (measured samples untouched)."""
    y = np.where(rec.measured, rec.y, rec.y + size)
    return dataclasses.replace(rec, y=y)


def test_measured_marks_exactly_the_grid_points_inside_bridged_gaps(tmp_path):
    path, t_read = _bursty_csv(tmp_path / "b.csv", 1)
    rec = sj.load_record(path, resample=0.1)
    assert rec.gaps and not rec.measured.all()
    # a grid point is measured when a stamp of the file lies on it (the bursts are on the grid)
    on_stamp = np.isclose(rec.time[:, None], t_read[None, :], atol=1e-9).any(axis=1)
    np.testing.assert_array_equal(rec.measured, on_stamp)
    plain = sj.Record.from_arrays(rec.time, rec.u, rec.y)
    assert plain.measured.all()
    # a window keeps the gaps it overlaps, and the mask follows
    cut = rec.window(5.0, None)
    np.testing.assert_array_equal(cut.measured, rec.measured[rec.time >= 5.0])


def test_split_masks_and_segments_leave_interpolated_samples_out(tmp_path):
    rec = sj.load_record(_bursty_csv(tmp_path / "b.csv", 2)[0], resample=0.1)
    train, val, info = sj.split_masks(rec, "time")
    assert not np.any((train | val) & ~rec.measured)
    assert np.all((train | val) == rec.measured)
    assert info["interpolated_left_out"] == int(np.sum(~rec.measured))
    sp = time_block(rec)
    for seg in (*sp.train, *sp.test):
        assert not np.any(seg.mask & ~rec.measured[seg.index])


@pytest.mark.slow  # suite time (session 70: 15-260 s on 2 cores)
def test_a_fit_does_not_see_interpolated_outputs(tmp_path):
    rec = sj.load_record(_bursty_csv(tmp_path / "b.csv", 3)[0], resample=0.1)
    _, doc_a, (tr, va, y_a) = fit_record(rec, refit=False, **FAST)
    _, doc_b, (_, _, y_b) = fit_record(_corrupt(rec), refit=False, **FAST)
    np.testing.assert_allclose(y_b, y_a, rtol=1e-9, atol=1e-9)
    for part in ("train", "validation"):
        assert doc_b["metrics"][part]["rmse"] == pytest.approx(doc_a["metrics"][part]["rmse"], rel=1e-9)
    assert doc_a["split"]["interpolated_left_out"] == int(np.sum(~rec.measured))
    assert any("interpolated across resampling gaps" in n for n in doc_a["notes"])
    # the corruption is visible to anything that looked at those samples: the test can fail
    assert np.sqrt(np.mean((_corrupt(rec).y - y_a) ** 2)) > 10 * doc_a["metrics"]["train"]["rmse"]


@pytest.mark.slow  # suite time (session 71: 17 s under load); a single fit ignoring interpolated outputs stays in the default suite
def test_joint_fit_and_leave_one_record_out_ignore_interpolated_outputs(tmp_path):
    recs = [sj.load_record(_bursty_csv(tmp_path / f"b{i}.csv", 10 + i)[0], resample=0.1) for i in range(2)]
    _, doc_a, _ = sj.fit_records(recs, **FAST)
    _, doc_b, _ = sj.fit_records([_corrupt(r) for r in recs], **FAST)
    assert doc_b["metrics"]["train"]["rmse"] == pytest.approx(doc_a["metrics"]["train"]["rmse"], rel=1e-9)
    for fa, fb in zip(doc_a["validation"]["folds"], doc_b["validation"]["folds"]):
        assert fb["model"]["rmse"] == pytest.approx(fa["model"]["rmse"], rel=1e-9)
        for k in fa["baselines"]:
            assert fb["baselines"][k]["rmse"] == pytest.approx(fa["baselines"][k]["rmse"], rel=1e-9)
    assert any("interpolated across resampling gaps" in n for n in doc_a["notes"])


@pytest.mark.parametrize("linear", ["sample", "marginalise", "profile"])
def test_posterior_mask_leaves_samples_out_of_the_likelihood(linear):
    truth, u, y = _small_cascade_problem()
    keep = np.ones(u.size, bool)
    keep[10:25] = keep[50:53] = False
    kw = dict(linear=linear, gain_scale=3.0 if linear == "marginalise" else 1e6, sigma=0.03)
    post = sj.Posterior(truth, (u, y), 0.5, mask=[keep], **kw)
    bad = sj.Posterior(truth, (u, np.where(keep, y, y + 4.0)), 0.5, mask=[keep], **kw)
    model, sigma = post.unpack(post.theta0)
    loglik = float(eqx.filter_jit(post._loglik)(model, sigma))
    assert float(eqx.filter_jit(bad._loglik)(model, sigma)) == pytest.approx(loglik, rel=1e-12)
    # against dense references on the kept rows only (the model still runs through every sample)
    A = np.asarray(model.hysteresis.features(model.thermal.effective_voltage(model.thermal.simulate(u, 0.5))))[keep]
    if linear == "sample":
        expected = stats.norm.logpdf(np.asarray(model.simulate(u, 0.5))[keep] - y[keep], scale=float(sigma)).sum()
    elif linear == "marginalise":
        cov = float(sigma) ** 2 * np.eye(int(keep.sum())) + 3.0**2 * A @ A.T
        expected = stats.multivariate_normal(mean=np.zeros(int(keep.sum())), cov=cov).logpdf(y[keep])
    else:
        w = np.linalg.lstsq(A, y[keep], rcond=None)[0]
        expected = stats.norm.logpdf(A @ w - y[keep], scale=float(sigma)).sum()
    assert loglik == pytest.approx(expected, rel=1e-6)
    whole = sj.Posterior(truth, (u, y), 0.5, **kw)
    assert float(eqx.filter_jit(whole._loglik)(model, sigma)) != pytest.approx(loglik, rel=1e-3)


def test_posterior_mask_bad_input():
    truth, u, y = _small_cascade_problem(n=30)
    with pytest.raises(ValueError, match="boolean array of shape"):
        sj.Posterior(truth, (u, y), 0.5, mask=[np.ones(29, bool)])
    with pytest.raises(ValueError, match="need at least 3"):
        sj.Posterior(truth, (u, y), 0.5, mask=[np.arange(30) < 2])


# suite time (34 s on a busy machine): the likelihood mask is checked against dense references above
@pytest.mark.slow
def test_smafl_sample_resamples_windows_and_leaves_interpolated_samples_out(tmp_path):
    from smafl_jax.cli import main as cli_main

    truth = sj.load_model(Path(__file__).resolve().parents[1] / "datasets" / "truth.json")
    k = np.concatenate([b * 12 + np.arange(8) for b in range(30)])  # bursts of 8 on a 0.5 s grid, 4 lost between
    t = 0.5 * k
    u = 3.5 + 3.0 * np.sin(2 * np.pi * t / 40.0)
    y = np.asarray(truth.simulate(np.interp(0.5 * np.arange(k[-1] + 1), t, u), 0.5))[k]
    y = y + 0.01 * np.random.default_rng(4).standard_normal(y.size)
    csv = tmp_path / "bursts.csv"
    sj.atomic_write_csv(csv, {"time_s": t, "voltage_V": u, "displacement_mm": y})
    out = tmp_path / "post"
    args = ["sample", str(csv), "--fit", str(Path(__file__).resolve().parents[1] / "datasets" / "truth.json")]
    args += ["--resample", "0.5", "--window", "6:", "--steps", "12", "--draws", "10", "--no-progress", "--out", str(out)]
    assert cli_main(args) == 0
    summary = json.loads((out / "summary.json").read_text())
    data = summary["data"]
    assert data["n_train_interpolated_left_out"] > 0
    assert any("resampled" in p for p in data["processing"]) and any("kept the window" in p for p in data["processing"])
