"""Record formats a new user brings (session 36 trial): time columns by name and unit, comment lines, duplicated
rows, blank measured cells, and the checks that catch a millisecond clock read as seconds or mixed sample times."""

import json
from decimal import Decimal

import numpy as np
import pytest

from smafl_jax import DataError
from smafl_jax.cli import build_parser
from smafl_jax.cli import main as cli_main
from smafl_jax.data import Record, check_record, check_records, load_record

N = 40
STEP_MS = "12.5"  # a sample time whose seconds (0.0125) are not a short binary fraction: the conversion must be exact


def ms_cells(n=N, step=STEP_MS):
    return [str(k * Decimal(step)) for k in range(n)]


def rows(time_cells, header_time, n=N, extra_header="", extra=None):
    """CSV text with the given time column; voltage and displacement are fixed functions of the row index."""
    lines = [f"{header_time},voltage_V,displacement_mm{extra_header}"]
    for k, tc in enumerate(time_cells):
        lines.append(f"{tc},{(k % 7) * 0.5:.3f},{0.01 * k:.4f}" + (extra[k] if extra else ""))
    return "\n".join(lines) + "\n"


def write(tmp_path, text, name="rec.csv"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def seconds_of(cells, divisor):
    """The stamps as the file would hold them in seconds (decimal strings, parsed once): what the conversion must give."""
    return np.array([float(Decimal(c) / divisor) for c in cells])


# -- time column by name and unit --------------------------------------------------------------------------------


@pytest.mark.parametrize("header", ["time [s]", "time (s)", "time", "Time", "t", "t_s", "Zeit [s]", "timestamp", "t/s"])
def test_time_column_in_seconds_recognised(tmp_path, header):
    cells = [str(k * Decimal("0.05")) for k in range(N)]
    r = load_record(write(tmp_path, rows(cells, header)))
    np.testing.assert_array_equal(r.time, seconds_of(cells, 1))
    assert r.dt == pytest.approx(0.05) and r.time_name == header
    note = [p for p in r.processing if p.startswith(f"time column '{header}'")]
    assert len(note) == 1 and "seconds" in note[0] and "->" not in note[0]


@pytest.mark.parametrize(
    "header,divisor,word",
    [("time_ms", 1000, "milliseconds"), ("time [ms]", 1000, "milliseconds"), ("t_ms", 1000, "milliseconds"),
     ("time (us)", 10**6, "microseconds"), ("time [µs]", 10**6, "microseconds"), ("Time_us", 10**6, "microseconds")],
)  # fmt: skip
def test_time_column_in_ms_or_us_converted_exactly(tmp_path, header, divisor, word):
    cells = ms_cells(step=STEP_MS if divisor == 1000 else "12500")
    r = load_record(write(tmp_path, rows(cells, header)))
    # bit for bit what the same stamps written in seconds read as
    np.testing.assert_array_equal(r.time, seconds_of(cells, divisor))
    assert r.dt == pytest.approx(0.0125, rel=1e-12)
    assert f"time column '{header}' (recognised by its name) read as {word} (unit from its name) -> seconds" in r.processing


def test_two_time_candidates_are_an_error_naming_both_and_the_option(tmp_path):
    cells = ms_cells()
    extra = [f",{c}" for c in cells]
    p = write(tmp_path, rows([str(k) for k in range(N)], "time", extra_header=",t_ms", extra=extra))
    with pytest.raises(DataError, match=r"several columns could be the time: \['time', 't_ms'\]; .*--time COL"):
        load_record(p)
    r = load_record(p, time="t_ms")  # the choice resolves it, with the unit from the name
    np.testing.assert_array_equal(r.time, seconds_of(cells, 1000))
    assert "time" in r.extra and any("'t_ms' (as chosen) read as milliseconds" in x for x in r.processing)


def test_no_time_column_error_suggests_the_option_and_T_is_not_a_time(tmp_path):
    p = write(tmp_path, rows([str(k) for k in range(N)], "T"))  # a single upper-case T is a temperature
    with pytest.raises(DataError, match=r"no time column 'time_s' .*columns are \['T', .*--time COL"):
        load_record(p)
    assert load_record(p, time="T").time_name == "T"
    with pytest.raises(DataError, match=r"no time column 'clock'.*--time COL"):
        load_record(p, time="clock")


def test_sidecar_names_the_time_column_and_its_unit(tmp_path):
    cells = ms_cells()
    p = write(tmp_path, rows(cells, "clock"))
    side = tmp_path / "rec.json"
    side.write_text(json.dumps({"time": "clock", "units": {"clock": "ms"}}))
    r = load_record(p)
    np.testing.assert_array_equal(r.time, seconds_of(cells, 1000))
    assert "time column 'clock' (as chosen) read as milliseconds (unit from the sidecar's units) -> seconds" in r.processing
    # the sidecar's unit also corrects a time_s column logged in milliseconds
    p2 = write(tmp_path, rows(cells, "time_s"), name="ms.csv")
    (tmp_path / "ms.json").write_text(json.dumps({"units": {"time_s": "ms"}}))
    np.testing.assert_array_equal(load_record(p2).time, seconds_of(cells, 1000))
    side.write_text(json.dumps({"time": "clock", "units": {"clock": "furlongs"}}))
    with pytest.raises(DataError, match=r"rec.json, column 'clock': units\['clock'\] = 'furlongs' is not a time unit"):
        load_record(p)
    side.write_text(json.dumps({"time": 3}))
    with pytest.raises(DataError, match="'time' must be a column name"):
        load_record(p)


def test_time_option_on_every_command_that_reads_records():
    parser = build_parser("*")
    for cmd in (["fit", "a.csv"], ["simulate", "m.json", "a.csv", "--out", "o.csv"], ["sample", "a.csv", "--fit", "f.json",
                "--out", "d"], ["diagnose", "a.csv", "--out", "d"], ["check", "a.csv"]):  # fmt: skip
        assert parser.parse_args(cmd + ["--time", "clock"]).time == "clock"
        assert parser.parse_args(cmd).time is None


def test_cli_simulate_with_time_option_in_ms(tmp_path, datasets_dir, capsys):
    """The same record with its clock in ms under another name simulates to the same output."""
    src = (datasets_dir / "minor_loop.csv").read_text().splitlines()
    n = 120
    ms = [src[0].replace("time_s", "clock_ms")]
    for line in src[1 : n + 1]:
        t, rest = line.split(",", 1)
        ms.append(f"{Decimal(t) * 1000},{rest}")
    sec = write(tmp_path, "\n".join(src[: n + 1]) + "\n", "sec.csv")
    msf = write(tmp_path, "\n".join(ms) + "\n", "ms.csv")
    model = str(datasets_dir / "truth.json")
    assert cli_main(["simulate", model, str(sec), "--out", str(tmp_path / "a.csv")]) == 0
    assert cli_main(["simulate", model, str(msf), "--time", "clock_ms", "--out", str(tmp_path / "b.csv")]) == 0
    assert "time column 'clock_ms' (as chosen) read as milliseconds" in capsys.readouterr().err
    a = np.loadtxt(tmp_path / "a.csv", delimiter=",", skiprows=1)
    b = np.loadtxt(tmp_path / "b.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(a, b)


def test_cli_fit_with_time_option(tmp_path, datasets_dir):
    src = (datasets_dir / "steps.csv").read_text().splitlines()[:301]
    p = write(tmp_path, "\n".join([src[0].replace("time_s", "Zeit (s)")] + src[1:]) + "\n")
    out = tmp_path / "fit"
    args = ["fit", str(p), "--model", "eupi", "--max-steps", "0", "--no-figures", "--split", "none", "--out", str(out)]
    assert cli_main(args + ["--time", "Zeit (s)"]) == 0
    doc = json.loads((out / "fit.json").read_text())
    assert doc["data"]["sample_time_s"] == pytest.approx(0.5) and doc["data"]["n_samples"] == 300
    assert any("time column 'Zeit (s)'" in x for x in doc["data"]["processing"])


# -- comment lines, duplicated rows ------------------------------------------------------------------------------


def test_leading_comment_lines_skipped_and_line_numbers_kept(tmp_path):
    cells = [str(k * Decimal("0.05")) for k in range(N)]
    text = "# logger v1.2 2026-11-29 rig 3\n\n  # sample rate 20 Hz\n" + rows(cells, "time_s")
    r = load_record(write(tmp_path, text))
    assert len(r) == N and "skipped 2 comment lines (starting with '#') before the header" in r.processing
    lines = text.splitlines()
    parts = lines[10].split(",")  # file line 11
    lines[10] = ",".join([parts[0], "oops", parts[2]])
    with pytest.raises(DataError, match=r"column 'voltage_V', row 11: non-numeric value 'oops'"):
        load_record(write(tmp_path, "\n".join(lines) + "\n", "bad.csv"))
    with pytest.raises(DataError, match="only comment lines"):
        load_record(write(tmp_path, "# nothing\n# here\n", "empty.csv"))


def dup_text(same=True):
    cells = [str(k * Decimal("0.05")) for k in range(N)]
    lines = rows(cells, "time_s").splitlines()
    copy = lines[11] if same else lines[11].rsplit(",", 1)[0] + ",9.9"
    return "\n".join(lines[:12] + [copy] + lines[12:]) + "\n", "\n".join(lines) + "\n"


def test_exact_duplicate_rows_need_resample_then_are_dropped(tmp_path):
    text, clean = dup_text(same=True)
    p = write(tmp_path, text)
    with pytest.raises(DataError, match=r"row 13: duplicated time value 0.5: line 13 repeats line 12 in every cell.*--resample"):
        load_record(p)
    r = load_record(p, resample="auto")
    ref = load_record(write(tmp_path, clean, "clean.csv"))
    np.testing.assert_array_equal(r.time, ref.time)
    np.testing.assert_array_equal(r.y, ref.y)
    assert any(x.startswith("dropped 1 exact duplicate row (every cell equal to the row before; lines 13)") for x in r.processing)


def test_duplicated_time_with_other_values_stays_an_error_with_advice(tmp_path):
    text, _ = dup_text(same=False)
    p = write(tmp_path, text)
    for kw in ({}, {"resample": "auto"}, {"resample": 0.05}):
        with pytest.raises(DataError, match=r"row 13: duplicated time value 0.5 with different values in \['displacement_mm'\]"):
            load_record(p, **kw)
    with pytest.raises(DataError, match="delete one of the two rows, or replace them by one row with their average"):
        load_record(p, resample="auto")


# -- blank cells in the measured column ------------------------------------------------------------------------------


def test_blank_measured_cells_kept_as_nan_when_the_output_is_optional(tmp_path):
    cells = [str(k * Decimal("0.05")) for k in range(N)]
    lines = rows(cells, "time_s").splitlines()
    for k, cell in ((5, ""), (9, "NaN"), (20, " ")):
        lines[k] = lines[k].rsplit(",", 1)[0] + f",{cell}"
    p = write(tmp_path, "\n".join(lines) + "\n")
    r = load_record(p, output="displacement_mm", require_output=False)
    assert r.output_name == "displacement_mm" and "displacement_mm" not in r.extra
    np.testing.assert_array_equal(np.flatnonzero(np.isnan(r.y)), [4, 8, 19])  # file lines 6, 10, 21
    good = np.isfinite(r.y)
    np.testing.assert_allclose(r.y[good], 0.01 * np.arange(N)[good])
    assert (
        f"output column 'displacement_mm': 3 of {N} cells empty or not finite (first at line 6): kept as NaN" in r.processing[0]
    )
    # the output of a fit stays required: a precise error
    with pytest.raises(DataError, match=r"column 'displacement_mm', row 6: empty cell"):
        load_record(p)
    # not asked for: left out, and the note says why
    r = load_record(p, require_output=False)
    assert r.y is None and "displacement_mm" not in r.extra
    assert "column 'displacement_mm' has 3 empty or NaN cells (first at line 6): left out" in r.processing
    # absent: no measured output, no error
    assert load_record(p, output="force_N", require_output=False).y is None
    # an infinite cell is no measurement either; a text cell makes it a text column, left out as any other
    lines[25] = lines[25].rsplit(",", 1)[0] + ",inf"
    r = load_record(write(tmp_path, "\n".join(lines) + "\n", "inf.csv"), output="displacement_mm", require_output=False)
    np.testing.assert_array_equal(np.flatnonzero(np.isnan(r.y)), [4, 8, 19, 24])
    lines[30] = lines[30].rsplit(",", 1)[0] + ",broken"
    r = load_record(write(tmp_path, "\n".join(lines) + "\n", "bad.csv"), output="displacement_mm", require_output=False)
    assert r.y is None and r.output_name is None
    assert "output column 'displacement_mm' is not numeric (line 31: 'broken'): left out, no measured output" in r.processing


# -- checks --------------------------------------------------------------------------------------------------------


def rec_at(dt, n=60, name="r", input_name="voltage_V"):
    t = dt * np.arange(n)
    u = 1 + np.sin(np.arange(n) / 5)
    return Record.from_arrays(t, u, 0.3 * u + 0.01 * np.cos(np.arange(n)), input_name=input_name, name=name)


def test_dt_mismatch_names_the_common_sample_time_or_lists_them():
    two = check_records([rec_at(0.1, name="cold"), rec_at(0.05, name="warm")], per_record=False)
    found = [f for f in two if f.kind == "dt_mismatch"]
    assert [f.record for f in found] == ["cold", "warm"]
    for f in found:
        assert "different sample times" in f.message and "cold 0.1 s, warm 0.05 s" in f.message
        assert "0.075" not in f.message
    three = [rec_at(0.1, name="a"), rec_at(0.1, name="b"), rec_at(0.05, name="c")]
    found = [f for f in check_records(three, per_record=False) if f.kind == "dt_mismatch"]
    assert [f.record for f in found] == ["c"] and "vs 0.1 s in 2 of the 3 records; resample to 0.1 s" in found[0].message
    assert found[0].size == pytest.approx(-0.05)
    tie = three + [rec_at(0.05, name="d")]
    found = [f for f in check_records(tie, per_record=False) if f.kind == "dt_mismatch"]
    assert sorted(f.record for f in found) == ["a", "b", "c", "d"] and all("no one is shared" in f.message for f in found)


def test_sample_time_finding_on_ms_read_as_seconds_only(tmp_path, datasets_dir):
    n = 1200
    ms = [str(k * Decimal(50)) for k in range(n)]
    slow = load_record(write(tmp_path, rows(ms, "time_s", n=n), "ms_as_s.csv"))
    found = [f for f in check_record(slow) if f.kind == "sample_time"]
    assert len(found) == 1 and "is 'time_s' in milliseconds?" in found[0].message and found[0].action == "check"
    assert found[0].size == pytest.approx(50.0)
    # the same stamps named as milliseconds: nothing to flag
    fixed = load_record(write(tmp_path, rows(ms, "time_ms", n=n), "ms.csv"))
    assert fixed.dt == pytest.approx(0.05) and not [f for f in check_record(fixed) if f.kind == "sample_time"]
    # a slow clock on a short record (the SMA wing record: 642 samples at 10 s) or on a measured input is plausible
    assert not [f for f in check_record(rec_at(10.0, n=642)) if f.kind == "sample_time"]
    assert not [f for f in check_record(rec_at(50.0, n=n, input_name="temperature_C")) if f.kind == "sample_time"]
    bundled = [load_record(p) for p in sorted(datasets_dir.glob("*.csv"))]
    assert not [f for f in check_records(bundled) if f.kind == "sample_time"]


def test_sample_time_not_flagged_on_real_records(real_data):
    wing = load_record(real_data / "sma_wing_forc_train.csv", output="displacement")
    assert wing.dt == pytest.approx(10.0) and "branch" in wing.extra
    assert not [f for f in check_record(wing) if f.kind == "sample_time"]


@pytest.mark.parametrize(
    ("header", "want_in", "want_out"),
    [
        ("time [s],voltage (V),displacement [mm]", "voltage (V)", "displacement [mm]"),  # names with their units
        ("Zeit [s],Spannung [V],Weg [mm]", "Spannung [V]", "Weg [mm]"),  # a voltage by its unit; the one column left
        ("t,V,x", "V", "x"),  # a voltage by its symbol
    ],
)
def test_input_and_output_recognised_by_name_unit_or_elimination(tmp_path, header, want_in, want_out):
    body = "".join(f"{0.05 * k:.2f},{k % 5:.1f},{0.1 * k:.2f}\n" for k in range(N))
    rec = load_record(write(tmp_path, header + "\n" + body))
    assert (rec.input_name, rec.output_name) == (want_in, want_out)
    assert any(f"input column '{want_in}'" in n for n in rec.processing) or want_in in ("voltage_V",)
    np.testing.assert_allclose(rec.u, [k % 5 for k in range(N)])


def test_an_unrecognised_output_among_several_columns_stays_an_error(tmp_path):
    body = "".join(f"{0.05 * k:.2f},{k % 5:.1f},{0.1 * k:.2f},{k}\n" for k in range(N))
    with pytest.raises(DataError, match=r"cannot tell which column is the output.*--output COLUMN"):
        load_record(write(tmp_path, "t,V,x,count\n" + body))
    with pytest.raises(DataError, match="several columns could be the input"):
        load_record(write(tmp_path, "t,U_in,V_set,displacement_mm\n" + "".join(f"{k},1,2,3\n" for k in range(N))))
