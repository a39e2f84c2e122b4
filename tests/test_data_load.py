"""Reading records (smafl_jax.data.load) and the split rules (smafl_jax.data.split)."""

import json

import numpy as np
import pytest

from smafl_jax import DataError, UserInputError
from smafl_jax.data import (
    Record,
    blocked_folds,
    branches,
    coverage,
    interleaved,
    leave_one_record_out,
    load_record,
    load_records,
    make_split,
    masks,
    resample_record,
    time_block,
    whole,
)
from smafl_jax.data.split import _directions  # private: white-box test of the split's direction labels

# -- helpers -----------------------------------------------------------------------------


def table(n=30, dt=0.1, delim=",", decimal=".", t0=0.0, extra=False, seed=0):
    """(text, columns) of a small record with known numbers."""
    rng = np.random.default_rng(seed)
    t = t0 + dt * np.arange(n)
    u = np.round(rng.uniform(0, 7, n), 3)
    y = np.round(rng.normal(0, 1, n), 4)
    cols = {"time_s": t, "voltage_V": u, "displacement_mm": y}
    if extra:
        cols["ambient_C"] = np.round(20 + 0.1 * np.arange(n), 2)
    lines = [delim.join(cols)]
    for k in range(n):
        cells = [f"{cols[c][k]:.6g}" for c in cols]
        if decimal != ".":
            cells = [c.replace(".", decimal) for c in cells]
        lines.append(delim.join(cells))
    return "\n".join(lines) + "\n", cols


def write(tmp_path, text, name="rec.csv", mode="w"):
    p = tmp_path / name
    if isinstance(text, bytes):
        p.write_bytes(text)
    else:
        p.write_text(text, encoding="utf-8")
    return p


# -- reading --------------------------------------------------------------------------------


def test_plain_csv_values_and_provenance(tmp_path):
    text, cols = table(extra=True)
    r = load_record(write(tmp_path, text))
    assert len(r) == 30 and r.dt == pytest.approx(0.1)
    np.testing.assert_allclose(r.u, cols["voltage_V"])
    np.testing.assert_allclose(r.y, cols["displacement_mm"])
    np.testing.assert_allclose(r.extra["ambient_C"], cols["ambient_C"])
    assert r.processing == () and r.gaps == () and len(r.sha256) == 64 and r.name == "rec"


@pytest.mark.parametrize(
    "delim,decimal,note",
    [(";", ",", "decimal commas"), ("\t", ",", "decimal commas"), (";", ".", None), ("\t", ".", None)],
)
def test_delimiters_and_decimal_comma(tmp_path, delim, decimal, note):
    text, cols = table(delim=delim, decimal=decimal)
    r = load_record(write(tmp_path, text))
    np.testing.assert_allclose(r.u, cols["voltage_V"])
    np.testing.assert_allclose(r.y, cols["displacement_mm"])
    np.testing.assert_allclose(r.time, cols["time_s"])
    assert (note is None and r.processing == ()) or any(note in p for p in r.processing)


def test_utf8_bom_is_stripped_and_reported(tmp_path):
    text, cols = table()
    r = load_record(write(tmp_path, b"\xef\xbb\xbf" + text.encode()))
    assert r.input_name == "voltage_V"
    np.testing.assert_allclose(r.time, cols["time_s"])
    assert any("byte-order mark" in p for p in r.processing)


def test_cp1252_file_is_read_with_a_note(tmp_path):
    text, _ = table()
    text = text.replace("displacement_mm", "displacement", 1)
    header, rest = text.split("\n", 1)
    raw = (header + ",temp_\xb0C\n").encode("cp1252") + "".join(line + ",1\n" for line in rest.splitlines()).encode()
    r = load_record(write(tmp_path, raw))
    assert "temp_°C" in r.extra and any("cp1252" in p for p in r.processing)


def test_binary_file_is_refused(tmp_path):
    with pytest.raises(DataError, match="binary file"):
        load_record(write(tmp_path, b"PK\x03\x04\x00\x00rest of a zip"))


def test_huge_field_is_a_clean_data_error(tmp_path):
    text, _ = table()
    lines = text.splitlines()
    lines[5] = lines[5] + "," + "9" * 200_000
    lines[0] = lines[0] + ",blob"
    lines = [ln if i in (0, 5) else ln + ",0" for i, ln in enumerate(lines)]
    with pytest.raises(DataError, match=r"row 6: cannot parse the CSV.*limit"):
        load_record(write(tmp_path, "\n".join(lines) + "\n"))


def test_unclosed_quote_is_a_clean_data_error(tmp_path):
    text, _ = table()
    lines = text.splitlines()
    lines[3] = lines[3].replace(",", ',"', 1)
    # the quote swallows the rest of the file into one cell: either the cell count or the field limit is named
    with pytest.raises(DataError, match=r"row \d+"):
        load_record(write(tmp_path, "\n".join(lines) + "\n" + "\n".join(lines[1:]) * 2000))


@pytest.mark.parametrize(
    "edit,expect",
    [
        (
            lambda L: L.__setitem__(6, L[6].replace(L[6].split(",")[1], "abc", 1)),
            r"column 'voltage_V', row 7: non-numeric value 'abc'",
        ),
        (
            lambda L: L.__setitem__(6, ",".join([L[6].split(",")[0], "", L[6].split(",")[2]])),
            r"column 'voltage_V', row 7: empty cell",
        ),
        (
            lambda L: L.__setitem__(4, L[4].rsplit(",", 1)[0] + ",nan"),
            r"column 'displacement_mm', row 5: non-finite value 'nan' \(lines 5\)",
        ),
        (
            lambda L: [L.__setitem__(k, L[k].rsplit(",", 1)[0] + ",inf") for k in (3, 9, 12)],
            r"row 4: non-finite value 'inf' \(lines 4, 10, 13\)",
        ),
        (
            lambda L: L.__setitem__(8, L[7].split(",")[0] + "," + L[8].split(",", 1)[1]),
            r"column 'time_s', row 9: duplicated time",
        ),
        (lambda L: L.__setitem__(8, "0.1" + "," + L[8].split(",", 1)[1]), r"column 'time_s', row 9: time goes backwards"),
        (lambda L: L.__setitem__(8, L[8].rsplit(",", 1)[0]), r"row 9: expected 3 cells, found 2"),
    ],
)
def test_bad_cells_are_named_by_line_and_column(tmp_path, edit, expect):
    text, _ = table()
    lines = text.splitlines()
    edit(lines)
    with pytest.raises(DataError, match=expect):
        load_record(write(tmp_path, "\n".join(lines) + "\n"))


def test_non_numeric_extra_column_is_left_out_with_a_note(tmp_path):
    text, _ = table()
    lines = text.splitlines()
    lines = [lines[0] + ",note"] + [ln + (",ok" if k == 3 else ",1") for k, ln in enumerate(lines[1:])]
    r = load_record(write(tmp_path, "\n".join(lines) + "\n"))
    assert "note" not in r.extra and any("'note' is not numeric" in p for p in r.processing)


def test_trailing_delimiter_column_is_ignored(tmp_path):
    text, cols = table()
    r = load_record(write(tmp_path, "\n".join(ln + "," for ln in text.splitlines()) + "\n"))
    np.testing.assert_allclose(r.y, cols["displacement_mm"])
    assert any("trailing" in p for p in r.processing)


def test_sidecar_load_units_and_metadata(tmp_path):
    text, _ = table()
    p = write(tmp_path, text)
    (tmp_path / "rec.json").write_text(json.dumps({"units": {"displacement_mm": "mm", "load": "g"}, "load": 200, "rig": "A"}))
    r = load_record(p)
    assert r.load == 200.0 and r.units["load"] == "g" and r.metadata["rig"] == "A"
    (tmp_path / "rec.json").write_text(json.dumps({"load": "heavy"}))
    with pytest.raises(DataError, match="'load' must be a finite number"):
        load_record(p)


def burst_text(rng, n_bursts=40, burst=10, dt=0.01, short_gap=0.03, long_gap=1.5, extra_col=False):
    """Cavatappi-like stamps: bursts of ``burst`` samples at ``dt``, short gaps between them, one long gap after the first."""
    t, k = [], 0.0
    for b in range(n_bursts):
        for _ in range(burst):
            t.append(k)
            k += dt
        k += (long_gap if b == 0 else short_gap) - dt
    t = np.round(np.array(t), 6)
    u = 5 + 3 * np.sin(0.7 * t)
    y = np.cos(0.5 * t) + 0.01 * rng.normal(size=t.size)
    lab = (t > t[-1] / 2).astype(int)
    head = "time_s,voltage_V,displacement_mm" + (",branch" if extra_col else "")
    lines = [head] + [f"{a:.6f},{b:.8f},{c:.8f}" + (f",{d}" if extra_col else "") for a, b, c, d in zip(t, u, y, lab)]
    return "\n".join(lines) + "\n", t, u, y


def test_bursts_refused_with_gap_and_fix(tmp_path, rng):
    text, *_ = burst_text(rng)
    with pytest.raises(
        DataError, match=r"row 12: irregular sampling: step 1.5 s vs median 0.01 s .* at t = 0.09 s.*--resample 0.01"
    ) as e:
        load_record(write(tmp_path, text))
    assert "longest 1.5 s" in str(e.value)


def test_bursts_resampled_onto_a_uniform_grid(tmp_path, rng):
    text, t, u, y = burst_text(rng, extra_col=True)
    r = load_record(write(tmp_path, text), resample=0.01)
    assert r.dt == 0.01
    np.testing.assert_allclose(np.diff(r.time), 0.01, atol=1e-12)
    assert r.time[0] == t[0] and r.time[-1] <= t[-1] + 1e-9 and len(r) == int(np.floor((t[-1] - t[0]) / 0.01 + 1e-9)) + 1
    # measured samples that fall on the grid keep their values; everything else is linear interpolation
    np.testing.assert_allclose(r.u, np.interp(r.time, t, u), atol=1e-7)  # the file holds 8 decimals
    np.testing.assert_allclose(r.y, np.interp(r.time, t, y), atol=1e-7)
    on_grid = np.isin(np.round(r.time, 6), np.round(t, 6))
    assert on_grid.sum() > 300
    np.testing.assert_allclose(r.y[on_grid], y[np.isin(np.round(t, 6), np.round(r.time, 6))], atol=1e-8)
    # every bridged interval is kept and counted; labels are held, not interpolated
    assert len(r.gaps) == 39 and r.gaps[0] == pytest.approx((0.09, 1.59))
    assert set(np.unique(r.extra["branch"])) == {0.0, 1.0}
    note = r.processing[-1]
    assert "39 gaps" in note and "linear interpolation" in note and "long gaps" in note and "0.09-1.59 s" in note


def test_resample_auto_keep_and_already_uniform(tmp_path, rng):
    text, t, _, _ = burst_text(rng)
    p = write(tmp_path, text)
    assert load_record(p, resample="auto").dt == pytest.approx(0.01)
    kept = load_record(p, irregular="keep")
    np.testing.assert_array_equal(kept.time, t)
    assert any("irregular time stamps kept" in x for x in kept.processing)
    uniform, cols = table()
    r = load_record(write(tmp_path, uniform, "u.csv"), resample=0.1)
    np.testing.assert_array_equal(r.y, cols["displacement_mm"])
    assert "already uniform" in r.processing[-1] and r.gaps == ()
    with pytest.raises(UserInputError, match="positive"):
        load_record(p, resample=-1.0)
    with pytest.raises(UserInputError, match="'auto'"):
        load_record(p, resample="fast")


def test_resample_record_downsampling_is_reported():
    t = np.arange(100) * 0.1
    r = Record.from_arrays(t, np.sin(t), np.cos(t), name="a")
    d = resample_record(r, 0.5)
    assert len(d) == 20 and "downsampled without an anti-alias filter" in d.processing[-1]


def test_from_arrays_validation():
    t = np.arange(20) * 0.5
    r = Record.from_arrays(t, t, 2 * t, name="syn", load=3.0)
    assert r.name == "syn" and r.load == 3.0 and r.dt == 0.5
    with pytest.raises(DataError, match="non-finite"):
        Record.from_arrays(t, np.where(t > 3, np.nan, t), t)
    with pytest.raises(DataError, match="irregular sampling"):
        Record.from_arrays(np.r_[t, 20.0], np.r_[t, 0], np.r_[t, 0])
    with pytest.raises(DataError, match="one length"):
        Record.from_arrays(t, t[:-1], t)


def test_load_records_folder_glob_and_mismatch(tmp_path):
    for k in range(3):
        write(tmp_path, table(seed=k)[0], f"r{k}.csv")
    by_folder = load_records(tmp_path)
    by_glob = load_records(str(tmp_path / "r*.csv"))
    by_list = load_records([tmp_path / "r2.csv", tmp_path / "r0.csv", tmp_path / "r2.csv"])
    assert [r.name for r in by_folder] == [r.name for r in by_glob] == ["r0", "r1", "r2"]
    assert [r.name for r in by_list] == ["r2", "r0"]
    odd = table(seed=9)[0].replace("voltage_V", "voltage")
    write(tmp_path, odd, "r3.csv")
    with pytest.raises(DataError, match=r"r3.csv: input column 'voltage' differs from 'voltage_V' in .*r0.csv"):
        load_records(tmp_path)
    with pytest.raises(DataError, match="no file matches"):
        load_records(str(tmp_path / "nothing*.csv"))


def test_real_cavatappi_needs_and_takes_resampling(real_data):
    files = sorted(real_data.glob("cavatappi_pneumatic_200g_*.csv"))
    assert len(files) == 4
    with pytest.raises(DataError, match=r"row 12: irregular sampling: step 1.439 s vs median 0.01 s.*--resample 0.01"):
        load_record(files[0], input="pressure", output="displacement_mm")
    recs = load_records(files, input="pressure", output="displacement_mm", resample=0.01)
    for r, f in zip(recs, files):
        raw = np.genfromtxt(f, delimiter=",", names=True)
        np.testing.assert_allclose(np.diff(r.time), 0.01, atol=1e-9)
        np.testing.assert_allclose(r.y, np.interp(r.time, raw["time_s"], raw["displacement_mm"]))
        assert r.gaps and max(b - a for a, b in r.gaps) > 1.0 and "bridged" in r.processing[-1]


# -- splits ------------------------------------------------------------------------------------


def rec(n=200, seed=0, branch=None, name="r", **kw):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.5
    u = np.abs(np.cumsum(rng.normal(0, 0.3, n)))
    extra = {} if branch is None else {"branch": branch}
    return Record.from_arrays(t, u, np.sin(u) + 0.01 * rng.normal(size=n), extra=extra, name=name, **kw)


def assert_partition(split, n):
    tr, te = masks(split, n)
    assert not np.any(tr & te) and np.all(tr | te)
    for s in split.train + split.test:
        np.testing.assert_array_equal(s.index, np.arange(s.index[0], s.index[-1] + 1))  # contiguous: simulated from its start


def test_time_block_masks_partition():
    r = rec(n=203)
    sp = time_block(r, 0.3)
    assert_partition(sp, 203)
    cut = round(203 * 0.7)
    assert len(sp.train[0]) == cut and len(sp.test[0]) == 203 and sp.test[0].mask.sum() == 203 - cut
    assert sp.n_scored() == (cut, 203 - cut)
    with pytest.raises(UserInputError):
        time_block(r, 1.2)


def test_branches_contiguous_labels_match_old_rule():
    lab = np.repeat(np.arange(11), 20).astype(float)
    r = rec(n=lab.size, branch=lab)
    for residue in (0, 1, 2):
        sp = branches(r, residue)
        assert_partition(sp, lab.size)
        assert sp.test_labels == tuple(str(k) for k in range(11) if k != 0 and k % 3 == residue)
        assert "0" in sp.train_labels
        assert all(s.record == "r" and "branch" not in s.extra for s in sp.train + sp.test)


def test_branches_non_contiguous_labels_use_sorted_positions():
    labels = [0, 3, 4, 7, 9, 12, 15]
    order = [7, 0, 12, 3, 15, 4, 9]  # records need not list branches in label order
    lab = np.repeat(np.array(order, float), 15)
    r = rec(n=lab.size, branch=lab)
    held = {res: branches(r, res).test_labels for res in (0, 1, 2)}
    assert held == {0: ("7", "15"), 1: ("3", "9"), 2: ("4", "12")}
    # the three folds hold out every branch but the first exactly once
    assert sorted(k for v in held.values() for k in v) == sorted(str(k) for k in labels[1:])
    for res in (0, 1, 2):
        sp = branches(r, res)
        assert_partition(sp, lab.size)
        for s in sp.test:
            assert np.all(lab[s.index] == float(s.label.split()[-1]))


def test_branch_errors():
    with pytest.raises(UserInputError, match="not one contiguous stretch"):
        branches(rec(n=60, branch=np.r_[np.zeros(20), np.ones(20), np.zeros(20)]), 1)
    with pytest.raises(UserInputError, match="holds out nothing"):
        branches(rec(n=40, branch=np.repeat([0.0, 1.0], 20)), 2)
    with pytest.raises(UserInputError, match="needs a numeric 'branch' column"):
        branches(rec(), 2)


def test_leave_one_record_out_and_whole():
    rs = [rec(n=50 + 10 * k, seed=k, name=f"r{k}") for k in range(4)]
    rs.append(rec(n=60, seed=9, name="forc", branch=np.repeat([0.0, 1.0, 2.0], 20)))
    folds = leave_one_record_out(rs)
    assert len(folds) == 5
    for i, sp in enumerate(folds):
        assert {s.record for s in sp.test} == {rs[i].name}
        assert {s.record for s in sp.train} == {r.name for j, r in enumerate(rs) if j != i}
        assert sum(len(s) for s in sp.test) == len(rs[i])
    assert len(folds[0].train) == 3 + 3  # the branch record trains as one segment per branch
    w = whole(rs)
    assert w.test == () and sum(int(s.mask.sum()) for s in w.train) == sum(len(r) for r in rs)
    with pytest.raises(UserInputError, match="at least 2 records"):
        leave_one_record_out(rs[:1])


def test_blocked_folds_hold_out_each_block_once():
    r = rec(n=103)
    folds = blocked_folds(r, 4)
    held = np.zeros(103, int)
    for sp in folds:
        assert_partition(sp, 103)
        assert len(sp.train[0]) == len(sp.test[0]) == 103  # the model runs through the whole record
        held += masks(sp, 103)[1]
        assert np.ptp(np.flatnonzero(sp.test[0].mask)) + 1 == sp.test[0].mask.sum()  # one contiguous block
    np.testing.assert_array_equal(held, 1)


def heat_hold_cool(n=300):
    """Rise, hold, then the only fall in the last fifth: the time block holds out the only cooling."""
    u = np.concatenate([np.linspace(0, 5, n // 5), np.full(3 * n // 5, 5.0), np.linspace(5, 0, n - n // 5 - 3 * n // 5)])
    t = np.arange(n) * 0.5
    return Record.from_arrays(t, u, np.tanh(u), name="hhc")


def test_interleaved_keeps_every_regime_in_training():
    r = heat_hold_cool()
    tb = coverage(time_block(r))
    assert tb["covered_fraction"] < 0.9 and "warning" in tb
    sp = make_split(r, "auto")
    assert sp.kind == "interleaved"
    assert_partition(sp, len(r))
    cov = coverage(sp)
    assert cov["covered_fraction"] > tb["covered_fraction"]
    d = _directions(r.u, np.ptp(r.u))
    tr, _ = masks(sp, len(r))
    assert all(np.any(tr & (d == k)) for k in (-1, 0, 1))  # rising, holding and falling samples all train
    assert np.all(tr[: len(r) // 10])  # the first block (the initial state) always trains
    assert interleaved(r, 0.3).test_labels == sp.test_labels


def test_make_split_auto_prefers_branch_then_time():
    lab = np.repeat(np.arange(6.0), 20)
    assert make_split(rec(n=lab.size, branch=lab)).kind == "branch"
    tri = np.abs(((np.arange(400) / 50.0) % 2) - 1)  # repeated triangles: the last 30 % repeats what trained
    r = Record.from_arrays(np.arange(400.0), tri, tri**2, name="tri")
    assert make_split(r).kind == "time"
    assert make_split(r, "none").kind == "all"
    with pytest.raises(UserInputError, match="unknown split"):
        make_split(r, "random")


def seg_split(train_us, test_us):
    rs = [Record.from_arrays(np.arange(len(u), dtype=float), u, u, name=f"s{i}") for i, u in enumerate(train_us + test_us)]
    segs = [whole(r).train[0] for r in rs]
    from smafl_jax.data import Split

    return Split("test", "constructed", tuple(segs[: len(train_us)]), tuple(segs[len(train_us) :]))


def test_coverage_constructed_cases():
    up = np.linspace(0, 1, 101)
    assert coverage(seg_split([up], [up[::-1]]))["covered_fraction"] == 0.0  # same levels, opposite direction
    assert coverage(seg_split([up], [np.linspace(0, 0.5, 51)]))["covered_fraction"] == 1.0
    # rising 0.505 -> 1.505 after training on 0 -> 1: covered up to 1 + 2 % of the span
    test = np.linspace(0.505, 1.505, 101)  # 0.01 per sample: rising (the threshold is 0.2 % of the span per sample)
    cov = coverage(seg_split([up], [test]))
    expect = np.mean(test <= 1.0 + 0.02 * 1.505)  # 2 % of the span of all inputs
    assert cov["covered_fraction"] == pytest.approx(expect, abs=1e-9)
    assert cov["by_direction"]["rising"]["heldout_samples"] == 101 and "warning" in cov


def test_coverage_matches_a_plain_loop(rng):
    segs_tr = [np.cumsum(rng.normal(0, 0.1, 80)) for _ in range(3)]
    segs_te = [np.cumsum(rng.normal(0, 0.1, 60)) for _ in range(2)]
    sp = seg_split(segs_tr, segs_te)
    span = np.ptp(np.concatenate(segs_tr + segs_te))
    seen = [(x, d) for u in segs_tr for x, d in zip(u, _directions(u, span))]
    hits = total = 0
    for u in segs_te:
        for x, d in zip(u, _directions(u, span)):
            total += 1
            hits += any(dd == d and abs(xx - x) <= 0.02 * span for xx, dd in seen)
    assert coverage(sp)["covered_fraction"] == pytest.approx(hits / total)


def test_temperature_and_pressure_inputs_are_recognised(tmp_path):
    t = np.arange(12) * 0.5
    rows = "".join(f"{a},{20 + k},{10 + 0.1 * k}\n" for k, a in enumerate(t))
    r = load_record(write(tmp_path, "time_s,temperature_C,length_mm\n" + rows))
    assert (r.input_name, r.output_name) == ("temperature_C", "length_mm")
    r = load_record(write(tmp_path, "time_s,pressure,displacement_mm\n" + rows))
    assert (r.input_name, r.output_name) == ("pressure", "displacement_mm")
    # a drive voltage wins over a logged temperature, which stays an extra column
    rows3 = "".join(f"{a},{20 + k},{1 + k % 3},{10 + 0.1 * k}\n" for k, a in enumerate(t))
    r = load_record(write(tmp_path, "time_s,temperature_C,voltage_V,length_mm\n" + rows3))
    assert r.input_name == "voltage_V" and "temperature_C" in r.extra
