"""Branch checks for models whose hysteresis sees its input directly, and for joint fits of several records.

A temperature -> length or pressure -> displacement model walks the input's own branches; a joint fit walks those of
every record.  Both now store ``data.trained_branches``, so `simulate_record` says when a new drive walks a branch no
training record walked (before: only cascades of one record had the check).
"""

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.identify import write_records_outputs
from smafl_jax.models import branch_check, trained_branches, trained_branches_of
from smafl_jax.report import fit_record, write_fit_outputs
from tests.reference import play_loop as reference_play

FAST = dict(model="eupi", max_steps=0, grid=dict(n_sym=6, n_alpha=0, n_asym=0, poly_order=2))
DT = 0.1


def play_loop(u, r):
    """Symmetric play operator (PAPER.md eq. 1, alpha = 1) started as if the input came down from above."""
    return reference_play(u, r, 1.0, u[0] + r)[:, 0]


def _sawtooth(n=600, period=100, lo=20.0, hi=70.0, rising=True):
    """Slow ramps one way, a one-sample jump back: the other branch is never walked."""
    ramp = lo + (hi - lo) * (np.arange(n) % period) / (period - 1)
    return ramp if rising else lo + hi - ramp


def _triangle(n=600, period=200, lo=22.0, hi=68.0):
    phase = (np.arange(n) % period) / period
    return lo + (hi - lo) * (1.0 - np.abs(2.0 * phase - 1.0))


def _record(u, name, seed=0):
    y = 0.02 * u + 0.5 * play_loop(u / 10.0, 0.6) + 0.002 * np.random.default_rng(seed).standard_normal(u.size)
    return sj.Record.from_arrays(np.arange(u.size) * DT, u, y, input_name="temperature_C", output_name="length_mm", name=name)


def _csv(path, u):
    sj.atomic_write_csv(path, {"time_s": np.arange(u.size) * DT, "temperature_C": u})
    return path


def _branch(res):
    return next((c for c in res.range_checks if c.get("what") == "branches"), None)


def test_trained_branches_of_keeps_each_trajectory_apart():
    a = _sawtooth(rising=True)
    joined = trained_branches(np.concatenate([a[:99], a[:99]]))
    apart = trained_branches_of([(a[:99], None), (a[:99], None)])
    assert apart["range"] == joined["range"]
    assert set(apart["rising"]) == set(range(apart["cells"]))
    # the only falling cells are those before the first move, not an invented fall from one record's end to the next
    assert set(apart["falling"]) <= {0, 1}
    falls = trained_branches_of([(a[:99], None), (a[:99][::-1], None)])
    assert set(falls["falling"]) == set(range(falls["cells"]))
    # a fall the check sees on new data is caught against the rising-only training
    assert "warning" in branch_check(a[:99][::-1], apart, dt=DT)


@pytest.mark.slow  # suite time (session 70: 15-260 s on 2 cores)
def test_direct_input_fit_stores_branches_and_simulate_warns(tmp_path):
    model, doc, masks = fit_record(_record(_sawtooth(), "train"), refit=True, **FAST)
    tb = doc["data"]["trained_branches"]
    assert len(tb["rising"]) > 0.9 * tb["cells"] and len(tb["falling"]) < 0.2 * tb["cells"]
    write_fit_outputs(tmp_path / "fit", _record(_sawtooth(), "train"), doc, masks, figures=False)
    fit_json = tmp_path / "fit" / "fit.json"
    warned = sj.simulate_record(fit_json, _csv(tmp_path / "tri.csv", _triangle()))
    chk = _branch(warned)
    assert chk is not None and chk["by_direction"]["falling"] > 0 and "warning" in chk
    assert any("branches its training never visited" in w for w in warned.warnings)
    same = sj.simulate_record(fit_json, _csv(tmp_path / "saw.csv", _sawtooth()))
    assert _branch(same) is not None and "warning" not in _branch(same)


def test_joint_fit_branches_are_the_union_of_its_records(tmp_path):
    tri = _csv(tmp_path / "tri.csv", _triangle())
    results = {}
    for label, pair in (("both rise", (True, True)), ("rise and fall", (True, False))):
        recs = [_record(_sawtooth(rising=r), f"r{i}", seed=i) for i, r in enumerate(pair)]
        _, doc, details = sj.fit_records(recs, split="none", **FAST)
        out = tmp_path / label.replace(" ", "_")
        write_records_outputs(out, recs, doc, details, figures=False)
        assert "2 records" in doc["data"]["trained_branches"]["rule"]
        results[label] = _branch(sj.simulate_record(out / "fit.json", tri))
    assert "warning" in results["both rise"]
    assert results["rise and fall"] is not None and "warning" not in results["rise and fall"]
