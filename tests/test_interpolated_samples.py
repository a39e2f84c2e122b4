"""Samples that resampling interpolated across a logger's gaps are not measurements: no fit weight, no score.

`Record.measured` marks them; `split_masks`, the joint fit of several records, the leave-one-record-out scores and the
diagnosis segments leave them out, while the model still runs through them.  Checked by changing only the
interpolated outputs of a record: nothing a fit reports may move.
"""

import dataclasses

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.data.split import time_block
from smafl_jax.report import fit_record

# initialiser only (bounded least squares for the gains): what enters the loss is under test, not the refinement
FAST = dict(model="eupi", max_steps=0, grid=dict(n_sym=6, n_alpha=0, n_asym=0, poly_order=2))


def play_loop(u, r):
    """Plain-loop symmetric play operator (PAPER.md eq. 1 with alpha = 1), started as if the input came down from above."""
    out = np.empty_like(u)
    f = u[0] + r
    for k, x in enumerate(u):
        f = max(x - r, min(x + r, f))
        out[k] = f
    return out


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
