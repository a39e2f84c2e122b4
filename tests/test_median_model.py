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
