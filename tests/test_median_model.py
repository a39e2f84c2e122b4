"""`MedianOfModels`: the sample-by-sample median of several models' outputs (numpy reference, JSON, CLI, bad input)."""

import json

import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.cli import main as cli_main


def _members():
    # three models that cross each other: different lags and offsets, so the median switches member over time
    return tuple(
        sj.JouleLag(thermal=sj.JouleThermal(k1=jnp.asarray(k1), k2=jnp.asarray(k2)), offset=jnp.asarray(c))
        for k1, k2, c in ((0.05, 0.02, 0.0), (0.5, 0.015, 0.1), (0.01, 0.01, -0.05))
    )


def test_median_matches_a_numpy_loop_and_vmaps(rng):
    ens = sj.MedianOfModels(_members())
    u = np.abs(rng.normal(2.0, 1.0, 400))
    ys = np.stack([np.asarray(sj.simulate(m, u, 0.1)) for m in ens.members])
    ref = np.array([sorted(ys[:, k])[1] for k in range(u.size)])  # the middle of three, one sample at a time
    got = np.asarray(sj.simulate(ens, u, 0.1))
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)
    assert len({int(np.argmin(np.abs(ys[:, k] - got[k]))) for k in range(u.size)}) >= 2  # not one member throughout
    batch = np.asarray(sj.simulate_batch(ens, np.stack([u, 0.5 * u]), 0.1))
    assert batch.shape == (2, u.size)
    np.testing.assert_allclose(batch[0], got, atol=1e-12)


def test_json_roundtrip_and_cli_simulate(tmp_path, rng, capsys):
    ens = sj.MedianOfModels(_members())
    path = tmp_path / "median.json"
    sj.save_model(path, ens)
    back = sj.load_model(path)
    assert type(back) is sj.MedianOfModels and len(back.members) == 3
    u = np.abs(rng.normal(2.0, 1.0, 200))
    np.testing.assert_allclose(np.asarray(sj.simulate(back, u, 0.1)), np.asarray(sj.simulate(ens, u, 0.1)), atol=0)
    t = 0.1 * np.arange(u.size)
    sj.atomic_write_csv(
        tmp_path / "run.csv", {"time_s": t, "voltage_V": u, "displacement_mm": np.asarray(sj.simulate(ens, u, 0.1))}
    )
    out = tmp_path / "sim.csv"
    assert (
        cli_main(
            [
                "simulate",
                str(path),
                str(tmp_path / "run.csv"),
                "--out",
                str(out),
                "--measured",
                "displacement_mm",
                "--metrics",
                str(tmp_path / "m.json"),
            ]
        )
        == 0
    )
    assert json.loads((tmp_path / "m.json").read_text())["rmse"] < 1e-9
    assert any("median of 3 models" in line for line in ens.describe())


def test_bad_members():
    with pytest.raises(ValueError, match="at least 2"):
        sj.MedianOfModels(_members()[:1])
    with pytest.raises(ValueError, match="no simulate"):
        sj.MedianOfModels((_members()[0], "cascade"))


@pytest.mark.slow  # three classes screened and fitted, each refitted: about a minute on 2 cores
def test_fit_record_median_of_the_classes(tmp_path, datasets_dir, capsys):
    """`smafl fit --median`: median_fit.json holds the median of every compared class, refitted on the whole record."""
    r = sj.load_record(datasets_dir / "minor_loop.csv")
    data = tmp_path / "short.csv"
    sj.atomic_write_csv(data, {"time_s": r.time[::2], "voltage_V": r.u[::2], "displacement_mm": r.y[::2]})
    out = tmp_path / "fit"
    argv = ["fit", str(data), "--median", "--max-steps", "3", "--no-figures", "--out", str(out)]
    assert cli_main(argv + ["--n-sym", "4", "--n-alpha", "2", "--n-asym", "2"]) == 0
    assert "median of cascade" in capsys.readouterr().out
    doc = json.loads((out / "fit.json").read_text())
    med = sj.load_model(out / "median_fit.json")
    names = [c["structure"] for c in doc["settings"]["structure_choice"]["candidates"]]
    assert doc["median"]["members"] == names and len(med.members) == len(names) >= 2
    # the kept class is one member, and the median file scores as its metrics say on the whole record
    kept = sj.load_model(out / "fit.json")
    i = names.index(doc["settings"]["structure_choice"]["chosen"])
    assert sj.model_to_dict(med.members[i]) == sj.model_to_dict(kept)
    rec = sj.load_record(data)
    y = np.asarray(sj.simulate(med, rec.u, rec.dt))
    assert doc["median"]["metrics"]["whole_record"]["rmse"] == pytest.approx(np.sqrt(np.mean((y - rec.y) ** 2)), rel=1e-9)
    assert "input_range" in json.loads((out / "median_fit.json").read_text())["data"]
    with pytest.raises(ValueError, match="model auto"):
        from smafl_jax.report import fit_record

        fit_record(rec, model="cascade", median=True)
