"""``--window START:END``: acting on a data-check finding ("cut the samples before the step") without editing the file."""

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax import DataError, UserInputError
from smafl_jax.cli import main
from smafl_jax.data import check_records
from smafl_jax.data._data import parse_window  # private: the --window option's parser, a CLI detail with no public path


def _zeroed_record():
    """A staircase record whose sensor was zeroed 9 s in (inside a hold): the output before is 45 mm low."""
    t = np.arange(3000) * 0.01
    u = np.repeat(np.random.default_rng(1).uniform(0.0, 2.0, 15), 200)
    y = 5.0 * u + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    y[t < 9.0] -= 45.0
    return sj.Record.from_arrays(t, u, y, input_name="pressure", output_name="displacement_mm")


def test_window_keeps_the_samples_inside_on_the_records_time_axis_and_says_so():
    rec = _zeroed_record()
    (jump,) = check_records([rec])
    assert jump.kind == "offset_jump" and jump.message.endswith("cut the 900 samples before the step (--window 9:)")
    cut = rec.window(9.0, None)
    assert len(cut) == 2100 and cut.time[0] == pytest.approx(9.0) and cut.time[-1] == rec.time[-1]
    np.testing.assert_array_equal(cut.y, rec.y[900:])
    assert cut.processing[-1] == "kept the window [9, 29.99] s of [0, 29.99] s (2100 of 3000 samples)"
    assert check_records([cut]) == []  # the finding is gone with the samples it named
    mid = rec.window(None, 12.5)
    assert len(mid) == 1251 and mid.time[-1] == pytest.approx(12.5)
    assert rec.window(-5.0, 100.0) is rec  # a window over the whole record changes nothing
    with pytest.raises(DataError, match=r"keeps 0 of 3000 samples \(the record spans \[0, 29.99\] s\)"):
        rec.window(40.0, None)
    with pytest.raises(DataError, match="start must be before its end"):
        rec.window(5.0, 5.0)


@pytest.mark.parametrize(
    ("text", "expect"), [("8.07:", (8.07, None)), (":120", (None, 120.0)), ("1:2.5", (1.0, 2.5)), (None, None)]
)
def test_parse_window(text, expect):
    assert parse_window(text) == expect


@pytest.mark.parametrize("text", [":", "5", "a:b", "3:1", "1:inf", "1:2:3"])
def test_parse_window_refuses_with_the_option_name(text):
    with pytest.raises(UserInputError, match="--window"):
        parse_window(text)


def test_check_cli_with_a_window_no_longer_reports_the_cut_fault(tmp_path, capsys):
    rec = _zeroed_record()
    path = tmp_path / "zeroed.csv"
    sj.atomic_write_csv(path, {"time_s": rec.time, "pressure": rec.u, "displacement_mm": rec.y})
    assert main(["check", str(path)]) == 0
    assert "offset_jump" in capsys.readouterr().out
    assert main(["check", str(path), "--window", "9:"]) == 0
    out = capsys.readouterr().out
    assert "offset_jump" not in out and "read: kept the window [9, 29.99] s of [0, 29.99] s (2100 of 3000 samples)" in out
    assert main(["check", str(path), "--window", "50:"]) == 2
    assert "keeps 0 of 3000 samples" in capsys.readouterr().err
