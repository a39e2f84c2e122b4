"""Batch use from Python and experiments/fit_folder.py (session-39 trial findings 6 and 7).

fit_many's errors name the record the caller named; fit_folder.py writes its summary with the `csv` module after every
record (an interrupted batch keeps the rows done), has held-out-over-noise and noise-SD columns, fits with `smafl fit`'s
options and defaults, and says so when its output folder holds earlier results.  The script runs in-process
(imported from experiments/) on two short records of the independent numpy plant.
"""

import csv
import sys
from pathlib import Path

import numpy as np
import pytest

import smafl_jax as sj

sys.path.insert(0, str(Path(__file__).parent))
import indep_plant
from repo_scripts import load_script

#: The cheapest fit that still has a validation split (the noise ratios need one): a tiny EUPI, initialiser only.
FAST = ["--model", "eupi", "--no-figures", "--n-sym", "3", "--n-alpha", "0", "--n-asym", "0", "--poly-order", "1"]
FAST += ["--max-steps", "0", "--memory", "zero", "--orientation", "rises"]


@pytest.fixture(scope="module")
def fit_folder():
    return load_script("experiments/fit_folder.py", "fit_folder_script")


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """Two 1.5-minute records at 5 Hz (450 samples each) of the independent plant."""
    d = tmp_path_factory.mktemp("records")
    for seed in (3, 4):
        indep_plant.write_csv(d / f"run_{seed:02d}.csv", indep_plant.make_record(seed, drive="multisine", rate_hz=5, minutes=1.5))
    return d


@pytest.fixture(scope="module")
def batch(fit_folder, folder, tmp_path_factory):
    """One whole batch over ``folder``: (output folder, return code)."""
    out = tmp_path_factory.mktemp("batch") / "out"
    return out, fit_folder.main([str(folder), "--out", str(out), *FAST])


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


# -- fit_many -------------------------------------------------------------------


def _pair(n=100):
    u = 2.0 + 2.0 * np.sin(np.linspace(0.0, 6.0 * np.pi, n))
    return u, 0.5 * u


def test_fit_many_errors_name_the_record():
    base = sj.EUPI.from_range(0.0, 4.0, n_sym=2, n_alpha=0, n_asym=0, poly_order=1)
    u, y = _pair()
    bad = (u[:2], y[:2])
    out = sj.fit_many(base, [(u, y), bad], dt=1.0, names=["run_01", "run_03"], progress=False, solver=None)
    assert isinstance(out[0], sj.FitResult)
    assert isinstance(out[1], sj.UserInputError)
    assert str(out[1]).startswith("fit data 'run_03' (1): need at least 3 samples, got 2")
    # without names: the entry's place in the batch (inside `fit` every entry is record 0)
    out = sj.fit_many(base, [bad, (u, y), (u, y[:-1])], dt=1.0, progress=False, solver=None)
    assert str(out[0]).startswith("fit data 0: need at least") and str(out[2]).startswith("fit data 2: the input u has")
    # an entry of several records (one actuator): the record inside it is named too
    out = sj.fit_many(base, [[(u, y), (u, y * np.nan)]], dt=1.0, names=["rig_b"], progress=False, solver=None)
    assert str(out[0]).startswith("fit data 'rig_b' (0), record 1: the output y is not finite at index 0")
    with pytest.raises(sj.UserInputError, match="got 1 names for 2 datasets"):
        sj.fit_many(base, [(u, y), (u, y)], dt=1.0, names=["only_one"], progress=False)
    with pytest.raises(sj.UserInputError, match=r"^fit data 'b' \(1\): dt \(the sample time in seconds\) is required"):
        sj.as_fit_data([(u, y, 1.0), (u, y)], names=["a", "b"])
    with pytest.raises(sj.UserInputError, match="got 1 names for 2 records"):
        sj.as_fit_data([(u, y, 1.0), (u, y, 1.0)], names=["a"])


# -- experiments/fit_folder.py ----------------------------------------------------


def test_fit_folder_summary_has_one_row_per_record_with_noise(batch, folder):
    out, rc = batch
    assert rc == 0
    rows = _rows(out / "summary.csv")
    assert [r["file"] for r in rows] == sorted(p.name for p in folder.glob("*.csv"))
    for r in rows:
        assert r["status"] == "ok", r["status"]
        noise = sj.load_model_file(out / Path(r["file"]).stem / "fit.json")[1]["metrics"]["noise"]
        assert float(r["val_over_noise"]) == pytest.approx(noise["validation_ratio"], rel=1e-3)
        assert float(r["train_over_noise"]) == pytest.approx(noise["train_ratio"], rel=1e-3)
        assert float(r["noise_sd"]) == pytest.approx(noise["sd"], rel=1e-3)
    md = (out / "summary.md").read_text().splitlines()
    assert len(md) == 2 + len(rows) and "val_over_noise" in md[0]


def test_fit_folder_quotes_with_the_csv_module(fit_folder, tmp_path):
    rows = [dict.fromkeys(fit_folder.COLUMNS, ""), dict.fromkeys(fit_folder.COLUMNS, "")]
    rows[0].update(file="a.csv", status='failed: column "x, y" missing\nsecond line')
    rows[1].update(file="b.csv", status="ok")
    fit_folder.write_summary(tmp_path, rows)
    assert _rows(tmp_path / "summary.csv") == rows


def test_interrupted_batch_keeps_the_rows_done(fit_folder, folder, tmp_path, monkeypatch, capsys):
    real = fit_folder.fit_record
    calls = []

    def interrupted_on_the_second(rec, **kw):
        calls.append(rec.name)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(rec, **kw)

    monkeypatch.setattr(fit_folder, "fit_record", interrupted_on_the_second)
    out = tmp_path / "out"
    assert fit_folder.main([str(folder), "--out", str(out), *FAST]) == 130
    rows = _rows(out / "summary.csv")
    assert [r["file"] for r in rows] == ["run_03.csv"] and rows[0]["status"] == "ok"
    assert rows[0]["val_over_noise"]
    assert not list(out.glob(".summary*")), "a temporary file was left behind"
    assert "interrupted during run_04.csv (2/2)" in capsys.readouterr().err


def test_rerun_says_the_folder_holds_results(batch, fit_folder, folder, monkeypatch, caplog):
    out, _ = batch
    before = (out / "summary.csv").read_bytes()

    def stop(rec, **kw):
        raise KeyboardInterrupt

    monkeypatch.setattr(fit_folder, "fit_record", stop)
    with caplog.at_level("WARNING", logger="smafl_jax"):
        assert fit_folder.main([str(folder), "--out", str(out), *FAST]) == 130
    assert any("already holds results" in r.getMessage() and "summary.csv" in r.getMessage() for r in caplog.records)
    assert (out / "summary.csv").read_bytes() == before  # nothing finished: the earlier summary is untouched


class _Stop(Exception):
    pass


@pytest.mark.parametrize(
    "flags", [[], ["--model", "cascade"], ["--model", "cascade", "--thresholds", "--no-tilts", "--memory", "rule"]]
)
def test_fit_folder_fits_what_smafl_fit_fits(fit_folder, folder, tmp_path, monkeypatch, flags):
    import smafl_jax.report._report_fit as report_fit  # private: the function `smafl fit` calls, replaced to see its keywords
    from smafl_jax.cli import build_parser

    seen = []

    def capture(rec, **kw):
        seen.append(kw)
        raise _Stop

    monkeypatch.setattr(report_fit, "fit_record", capture)
    monkeypatch.setattr(fit_folder, "fit_record", capture)
    record = sorted(folder.glob("*.csv"))[0]
    args = build_parser("fit").parse_args(["fit", str(record), "--out", str(tmp_path / "cli"), *flags])
    with pytest.raises(_Stop):
        args.func(args)
    with pytest.raises(_Stop):
        fit_folder.main([str(folder), "--out", str(tmp_path / "batch"), *flags])
    cli, script = seen
    assert cli.pop("progress") and not script.pop("progress")  # the CLI's progress lines; the batch prints one per record
    assert script == cli
    assert script["model"] == (flags[1] if flags else "auto")
