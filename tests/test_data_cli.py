import json
import subprocess
import sys

import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.cli import main as cli_main


def write(tmp_path, text, name="rec.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def good_csv(n=20, dt=0.1, extra=""):
    lines = ["time_s,voltage_V,displacement_mm" + (",ambient_C" if extra else "")]
    for k in range(n):
        lines.append(f"{k * dt:.4f},{k % 7 * 0.5},{k * 0.01}" + (f",{20 + k * 0.1}" if extra else ""))
    return "\n".join(lines) + "\n"


def test_load_good_record_with_extra_and_sidecar(tmp_path):
    p = write(tmp_path, good_csv(extra=True))
    (tmp_path / "rec.json").write_text(json.dumps({"units": {"displacement_mm": "mm"}, "description": "demo"}))
    r = sj.load_record(p)
    assert len(r) == 20 and r.dt == pytest.approx(0.1)
    assert r.input_name == "voltage_V" and r.output_name == "displacement_mm"
    assert "ambient_C" in r.extra and r.units["displacement_mm"] == "mm" and r.description == "demo"
    assert len(r.sha256) == 64


def test_select_other_columns(real_data):
    r = sj.load_record(real_data / "niti_wire_water_step_01.csv", input="temperature_front_C", output="length_signal")
    assert r.dt == pytest.approx(0.1) and "temperature_end_C" in r.extra
    # a real recording gap is reported, not silently resampled
    with pytest.raises(sj.DataError, match=r"row 12: irregular sampling: step 1.439 s vs median 0.01 s"):
        sj.load_record(real_data / "cavatappi_pneumatic_200g_s1_t1.csv", input="pressure", output="displacement_mm")


@pytest.mark.parametrize(
    "text,expect",
    [
        ("", "file is empty"),
        ("time_s,voltage_V,displacement_mm\n", "no data rows"),
        ("clock,voltage_V,displacement_mm\n" + "0,1,2\n" * 12, "no time column 'time_s'"),
        (good_csv().replace("0.4000,2.0,0.04", "0.4000,abc,0.04"), "column 'voltage_V', row 6: non-numeric value 'abc'"),
        (good_csv().replace("0.4000,2.0,0.04", "0.4000,2.0,nan"), "column 'displacement_mm', row 6: non-finite"),
        (good_csv().replace("0.4000,2.0,0.04", "0.4000,2.0,inf"), "column 'displacement_mm', row 6: non-finite"),
        (good_csv().replace("0.4000,", "0.3000,"), "row 6: duplicated time"),
        (good_csv().replace("0.4000,", "0.2000,"), "row 6: time goes backwards"),
        (good_csv().replace("0.4000,", "0.4500,"), "row 6: irregular sampling"),
        (good_csv(n=5), "too few samples"),
        (good_csv().replace("0.4000,2.0,0.04", "0.4000,2.0"), "row 6: expected 3 cells"),
        ("time_s,a,b\n" + "".join(f"{k},1,2\n" for k in range(12)), "cannot tell which column is the input"),
    ],
)
def test_bad_records_name_file_column_row(tmp_path, text, expect):
    p = write(tmp_path, text)
    with pytest.raises(sj.DataError) as ei:
        sj.load_record(p)
    assert str(p) in str(ei.value)
    assert expect in str(ei.value)


def test_missing_file_and_column(tmp_path):
    with pytest.raises(sj.DataError, match="file not found"):
        sj.load_record(tmp_path / "nope.csv")
    p = write(tmp_path, good_csv())
    with pytest.raises(sj.DataError, match="no input column 'pressure'"):
        sj.load_record(p, input="pressure")
    with pytest.raises(sj.DataError, match="no output column 'force'"):
        sj.load_record(p, output="force")


def test_model_json_roundtrip(tmp_path, rng):
    m = sj.Cascade.from_range(7.4, n_sym=3, n_alpha=2, n_asym=2)
    m = sj.constrain(sj.unconstrain(m))
    path = tmp_path / "m.json"
    sj.save_model(path, m, note="x")
    m2 = sj.load_model(path)
    assert type(m2) is sj.Cascade and m2.hysteresis.init == m.hysteresis.init
    u = rng.uniform(0, 7, 64)
    np.testing.assert_array_equal(np.asarray(sj.simulate(m, u, 0.5)), np.asarray(sj.simulate(m2, u, 0.5)))
    doc = json.loads(path.read_text())
    assert doc["model"]["thermal"]["k1"] == pytest.approx(float(m.thermal.k1))
    doc["model"]["thermal"]["bogus"] = 1
    path.write_text(json.dumps(doc))
    with pytest.raises(sj.UserInputError, match="no field 'bogus'"):
        sj.load_model(path)


def test_cli_simulate_roundtrip(tmp_path, datasets_dir, capsys):
    out = tmp_path / "sim.csv"
    rc = cli_main(["simulate", str(datasets_dir / "truth.json"), str(datasets_dir / "minor_loop.csv"), "--out", str(out)])
    assert rc == 0
    header = out.read_text().splitlines()[0].split(",")
    assert header == ["time_s", "voltage_V", "output_model"]
    sim = np.loadtxt(out, delimiter=",", skiprows=1)
    rec = sj.load_record(datasets_dir / "minor_loop.csv")
    # the bundled record is the truth plus 3 um sensor noise
    assert np.sqrt(np.mean((sim[:, 2] - rec.y) ** 2)) < 0.005
    rc = cli_main(["simulate", str(datasets_dir / "truth.json"), str(datasets_dir / "minor_loop.csv"), "--out", str(out)])
    assert "replacing existing" in capsys.readouterr().err


def test_cli_simulate_scores_against_measured_column(tmp_path, datasets_dir, capsys):
    out, mfile = tmp_path / "sim.csv", tmp_path / "m.json"
    args = ["simulate", str(datasets_dir / "truth.json"), str(datasets_dir / "minor_loop.csv"), "--out", str(out)]
    assert cli_main(args + ["--measured", "displacement_mm", "--metrics", str(mfile)]) == 0
    sim = np.loadtxt(out, delimiter=",", skiprows=1)
    assert out.read_text().splitlines()[0].split(",") == ["time_s", "voltage_V", "output_model", "displacement_mm"]
    m = json.loads(mfile.read_text())
    err = sim[:, 3] - sim[:, 2]
    assert m["rmse"] == pytest.approx(np.sqrt(np.mean(err**2)), rel=1e-6) and m["rmse"] < 0.005
    assert m["e_r_percent"] == pytest.approx(np.max(np.abs(err)) / np.ptp(sim[:, 3]) * 100, rel=1e-6)
    # the true model on its own noisy record leaves only the noise: RMSE about 1x the noise SD estimated from the data
    assert m["noise"]["scored_ratio"] == pytest.approx(m["rmse"] / m["noise"]["sd"], rel=1e-12)
    assert 0.8 < m["noise"]["scored_ratio"] < 1.25
    printed = capsys.readouterr().out
    assert "against measured 'displacement_mm'" in printed and "the measured output's noise SD" in printed
    assert cli_main(args + ["--measured", "force_N"]) == 2


def test_cli_user_errors_exit_2_without_traceback(tmp_path, datasets_dir):
    bad = write(tmp_path, good_csv().replace("0.4000,2.0,0.04", "0.4000,oops,0.04"))
    cmd = [
        sys.executable,
        "-m",
        "smafl_jax.cli",
        "simulate",
        str(datasets_dir / "truth.json"),
        str(bad),
        "--out",
        str(tmp_path / "o.csv"),
    ]
    res = subprocess.run(cmd, capture_output=True, text=True)
    assert res.returncode == 2
    assert "Traceback" not in res.stderr and "row 6" in res.stderr and "voltage_V" in res.stderr
    res = subprocess.run(
        cmd[:5] + [str(tmp_path / "missing.csv"), "--out", str(tmp_path / "o.csv")], capture_output=True, text=True
    )
    assert res.returncode == 2 and "file not found" in res.stderr and "Traceback" not in res.stderr
    assert not (tmp_path / "o.csv").exists()


def test_a_gain_a_hair_below_zero_is_round_off_saved_and_read_as_zero(tmp_path):
    """A fit ending on the gains' bound may leave -4e-19 (a new-user trial: a diagnosis' base_fit.json that neither
    `smafl simulate` nor `smafl sample` would read); a clearly negative gain is still refused."""
    import dataclasses

    m = sj.Cascade.from_range(7.4, n_sym=3, n_alpha=2, n_asym=2)
    w = np.asarray(m.hysteresis.w, dtype=np.float64).copy()
    w.flat[1] = -4.4e-19 * max(1.0, float(np.max(np.abs(w))))
    tiny = dataclasses.replace(m, hysteresis=dataclasses.replace(m.hysteresis, w=jnp.asarray(w)))
    sj.save_model(tmp_path / "saved.json", tiny)
    doc = json.loads((tmp_path / "saved.json").read_text())
    assert np.min(doc["model"]["hysteresis"]["w"]) >= 0.0  # written as 0
    doc["model"]["hysteresis"]["w"] = w.tolist()  # a file written before the clip: read as 0 too
    (tmp_path / "old.json").write_text(json.dumps(doc))
    assert float(np.min(np.asarray(sj.load_model(tmp_path / "old.json").hysteresis.w))) == 0.0
    w.flat[1] = -1e-3 * max(1.0, float(np.max(np.abs(w))))
    doc["model"]["hysteresis"]["w"] = w.tolist()
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(sj.UserInputError, match=r"model\.hysteresis\.w: must be >= 0"):
        sj.load_model(tmp_path / "bad.json")
