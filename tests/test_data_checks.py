"""Data checks (smafl_jax.data.checks) and the `smafl check` command.

Every detector must find its fault planted at a random place with a random size
in a synthetic record, and clean records (hysteretic synthetic records at any
scale, noise-only records, the bundled datasets) must give no finding.
"""

import json
import shutil

import numpy as np
import pytest

from smafl_jax.cli import main as cli_main
from smafl_jax.data import Record, check_record, check_records, load_record, load_records

SEEDS = range(6)


# -- synthetic records ---------------------------------------------------------------------


def play(u, r):
    out, s = np.empty_like(u), u[0]
    for k, x in enumerate(u):
        s = min(max(s, x - r), x + r)
        out[k] = s
    return out


def lag(x, a):
    out, s = np.empty_like(x), x[0]
    for k, v in enumerate(x):
        s += a * (v - s)
        out[k] = s
    return out


def clean(seed, n=3000, noise=0.004):
    """A hysteretic, lagged response to a rest hold then random ramps and holds, at a random scale and offset.

    Returns ``(record, holds)``: ``holds`` lists ``(start, stop)`` of the input holds (the first is the rest hold).
    """
    rng = np.random.default_rng(seed)
    parts, holds, level, k = [np.zeros(int(rng.integers(200, 400)))], [], 0.0, 0
    holds.append((0, parts[0].size))
    k = parts[0].size
    while k < n:
        new = float(rng.uniform(0, 1))
        ramp = np.linspace(level, new, int(rng.integers(15, 40)))
        hold = np.full(int(rng.integers(100, 300)), new)
        holds.append((k + ramp.size, k + ramp.size + hold.size))
        parts += [ramp, hold]
        k += ramp.size + hold.size
        level = new
    u = np.concatenate(parts)[:n]
    holds = [(a, min(b, n)) for a, b in holds if a < n]
    h = play(u, 0.08)
    y = lag(h + 0.4 * h**2, 0.03)
    y = y + noise * rng.normal(size=n)
    u = u + 0.002 * rng.normal(size=n)
    sy, sx = 10 ** rng.uniform(-3, 3), 10 ** rng.uniform(-2, 2)
    off = rng.uniform(-100, 100)
    t = np.arange(n) * 10 ** rng.uniform(-3, 1)
    return Record.from_arrays(t, sx * u, off + sy * y, name=f"clean{seed}"), holds


def with_y(rec, y, name=None):
    return Record.from_arrays(rec.time, rec.u, y, name=name or rec.name)


def span(rec):
    return float(np.percentile(rec.y, 99) - np.percentile(rec.y, 1))


# -- clean records -----------------------------------------------------------------------------


@pytest.mark.parametrize("seed", SEEDS)
def test_clean_synthetic_record_has_no_finding(seed):
    rec, _ = clean(seed)
    assert check_record(rec) == []


@pytest.mark.parametrize("seed", SEEDS)
def test_noise_only_record_has_no_finding(seed):
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(200, 5000))
    scale = 10 ** rng.uniform(-4, 4)
    u = np.cumsum(rng.normal(size=n))
    rec = Record.from_arrays(np.arange(n) * 0.01, u, scale * rng.normal(size=n), name="noise")
    assert check_record(rec) == []


def test_constant_columns_are_reported():
    t = np.arange(300) * 0.1
    found = check_record(Record.from_arrays(t, np.sin(t), np.full(300, 2.5), name="c"))
    assert [(f.kind, f.column, f.action) for f in found] == [("constant", "output", "drop")]
    found = check_record(Record.from_arrays(t, np.zeros(300), np.sin(t), name="c"))
    assert [(f.kind, f.column) for f in found] == [("constant", "input")]


@pytest.mark.parametrize("seed", SEEDS)
def test_output_steps_that_follow_input_steps_are_no_jump(seed):
    """A fast system: the output steps at once with each input step (the input-holds rule keeps it clean)."""
    rng = np.random.default_rng(200 + seed)
    u = np.repeat(rng.uniform(0, 1, 30), rng.integers(20, 80, 30))
    y = np.tanh(3 * u) + 0.003 * rng.normal(size=u.size)
    rec = Record.from_arrays(np.arange(u.size) * 1.0, u + 0.002 * rng.normal(size=u.size), y, name="fast")
    assert check_record(rec) == []


@pytest.mark.parametrize("seed", SEEDS)
def test_fast_transients_are_no_spikes(seed):
    """Cusps two to four samples wide: sharp, but the neighbours change fast too (the local-change rule)."""
    rng = np.random.default_rng(300 + seed)
    k = np.arange(1500)
    y = 0.002 * rng.normal(size=k.size)
    for c in rng.choice(np.arange(30, 1470, 50), 8, replace=False):
        y += rng.uniform(0.3, 1) * np.exp(-np.abs(k - c) / rng.uniform(2, 4))
    rec = Record.from_arrays(k * 0.01, np.cumsum(rng.normal(size=k.size)), y, name="cusps")
    assert check_record(rec) == []


@pytest.mark.parametrize("name", ["steps", "main_loop", "minor_loop"])
def test_bundled_datasets_are_clean(datasets_dir, name):
    assert check_record(load_record(datasets_dir / f"{name}.csv")) == []


# -- planted faults --------------------------------------------------------------------------


@pytest.mark.parametrize("seed", SEEDS)
def test_zeroing_offset_at_the_start_is_found_and_cut(seed):
    rec, holds = clean(seed)
    rng = np.random.default_rng(1000 + seed)
    a, b = holds[0]
    k = int(rng.integers(a + 15, b - 15))
    d = float(rng.choice([-1, 1]) * rng.uniform(0.1, 2.0) * span(rec))
    y = rec.y.copy()
    y[:k] += d  # the sensor reads off by d until it is zeroed at sample k
    found = check_record(with_y(rec, y))
    assert [f.kind for f in found] == ["offset_jump"]
    f = found[0]
    assert f.index == (0, k) and f.action == "cut"
    assert f.size == pytest.approx(d, rel=0.1) and f.time_s == (rec.time[0], rec.time[k - 1])


@pytest.mark.parametrize("seed", SEEDS)
def test_offset_stretch_inside_a_hold_is_found_and_marked(seed):
    rec, holds = clean(seed)
    rng = np.random.default_rng(2000 + seed)
    inner = [(a, b) for a, b in holds[1:] if b - a >= 120 and a > 100 and b < len(rec) - 100]
    a, b = inner[int(rng.integers(len(inner)))]
    s0 = int(rng.integers(a + 15, b - 60))
    s1 = int(rng.integers(s0 + 30, b - 15))
    d = float(rng.choice([-1, 1]) * rng.uniform(0.1, 2.0) * span(rec))
    y = rec.y.copy()
    y[s0:s1] += d
    found = check_record(with_y(rec, y))
    assert [f.kind for f in found] == ["offset_jump"]
    assert found[0].index == (s0, s1) and found[0].action == "mark"
    assert found[0].size == pytest.approx(d, rel=0.1)


@pytest.mark.parametrize("seed", SEEDS)
def test_spikes_are_found_where_planted(seed):
    rec, _ = clean(seed)
    rng = np.random.default_rng(3000 + seed)
    y, n = rec.y.copy(), len(rec)
    planted = []
    for pos in np.sort(rng.choice(np.arange(20, n - 20, 60), size=3, replace=False)):
        w = int(rng.integers(1, 4))
        d = float(rng.choice([-1, 1]) * rng.uniform(0.1, 1.0) * span(rec))
        y[pos : pos + w] += d
        planted.append((int(pos), int(pos) + w, d))
    found = check_record(with_y(rec, y))
    assert {f.kind for f in found} == {"spike"} and len(found) == len(planted)
    for f, (a, b, d) in zip(found, planted):
        assert a <= f.index[0] and f.index[1] <= b and f.action == "mark"
        assert np.sign(f.size) == np.sign(d) and abs(f.size) == pytest.approx(abs(d), rel=0.3)


def test_input_spike_is_found_in_the_input_column():
    rec, _ = clean(0)
    u = rec.u.copy()
    u[1234] += 0.5 * np.ptp(u)
    found = check_record(Record.from_arrays(rec.time, u, rec.y, name="x"))
    assert [(f.kind, f.column, f.index) for f in found] == [("spike", "input", (1234, 1235))]


def pwm_record(seed, n=6000):
    """A PWM voltage whose duty drifts close to 0 and 1 (pulses of 1-3 samples) and a first-order-lag response."""
    rng = np.random.default_rng(5000 + seed)
    period = int(rng.integers(12, 40))
    k = np.arange(n)
    duty = 0.5 + 0.49 * np.sin(2 * np.pi * k / rng.uniform(1500, 3000) + rng.uniform(0, 2 * np.pi))
    high = float(rng.uniform(2, 6))
    u = high * ((k % period) < np.round(duty * period)) + 0.003 * rng.normal(size=n)
    y = np.zeros(n)
    for i in range(1, n):
        y[i] = y[i - 1] + 0.02 * (u[i - 1] ** 2 / high**2 - y[i - 1])
    return Record.from_arrays(k * 0.04, u, y + 0.002 * rng.normal(size=n), name="pwm"), high


@pytest.mark.parametrize("seed", SEEDS)
def test_short_pwm_pulses_are_no_input_spikes(seed):
    """At a duty near 0 or 1 a PWM pulse lasts 1-3 samples: an excursion to a level the drive dwells at is switching."""
    rec, _ = pwm_record(seed)
    assert check_record(rec) == []


@pytest.mark.parametrize("seed", SEEDS)
def test_input_spike_off_the_pwm_levels_is_found(seed):
    rec, high = pwm_record(seed)
    u = rec.u.copy()
    # inside a pulse or a pause (a spike on an edge is off only one side's trend), high or low: either way a value
    # the drive never holds
    on = u > high / 2
    k = next(i for i in range(3000, len(u)) if (on[i - 5 : i + 6] == on[i]).all())
    u[k] += 0.8 * high
    found = check_record(Record.from_arrays(rec.time, u, rec.y, name="x"))
    assert [(f.kind, f.column, f.index) for f in found] == [("spike", "input", (k, k + 1))]


def test_independent_low_duty_pwm_record_is_no_zeroed_sensor(tmp_path):
    """A clean 5 Hz PWM record from the independent plant (length sensor, warm start): the pulses at a low duty leave
    the input's median at 0 while the output moves with the duty; that is no 'input holds' (it was flagged as a zeroed
    sensor with the advice to cut 203 samples)."""
    import indep_plant

    r = indep_plant.make_record(1, drive="pwm", rate_hz=5, minutes=5, start="warm", orientation="length")
    indep_plant.write_csv(tmp_path / "pwm5.csv", r)
    assert check_record(load_record(tmp_path / "pwm5.csv")) == []


@pytest.mark.parametrize("seed", SEEDS)
def test_stuck_stretch_is_found(seed):
    rec, _ = clean(seed)
    rng = np.random.default_rng(4000 + seed)
    n = len(rec)
    L = int(rng.integers(30, 200))
    a = int(rng.integers(50, n - L - 50))
    y = rec.y.copy()
    y[a : a + L] = y[a]
    found = check_record(with_y(rec, y))
    flat = [f for f in found if f.kind == "flat"]
    assert len(flat) == 1 and flat[0].index == (a, a + L) and flat[0].action == "mark"
    # a stuck sensor that lets go while the input holds also steps: then an offset jump at the stretch's end
    assert all(f.kind == "offset_jump" and a + L in f.index for f in found if f.kind != "flat")
    # stuck from the start: cut
    y = rec.y.copy()
    y[:L] = y[L]
    found = check_record(with_y(rec, y))
    assert [(f.kind, f.index, f.action) for f in found] == [("flat", (0, L + 1), "cut")]


@pytest.mark.parametrize("seed", SEEDS)
def test_clipped_output_is_found(seed):
    rec, _ = clean(seed)
    rng = np.random.default_rng(5000 + seed)
    top = float(np.percentile(rec.y, rng.uniform(75, 95)))
    y = np.minimum(rec.y, top)
    found = check_record(with_y(rec, y))
    # one excursion above the limit that lasts to the record's end reads as a stuck value; either names the samples
    assert found and {f.kind for f in found} <= {"clipped", "flat"} and "clipped" in {f.kind for f in found}
    assert all(f.action in ("mark", "cut") and y[f.index[0]] == y[f.index[1] - 1] == top for f in found)
    clip = next(f for f in found if f.kind == "clipped")
    assert (
        clip.index == (np.flatnonzero(y == top)[0], np.flatnonzero(y == top)[-1] + 1)
        and f"{np.sum(y == top)} samples" in clip.message
    )


def irregular_csv(tmp_path, seed, name="burst.csv"):
    rng = np.random.default_rng(seed)
    burst, dt = int(rng.integers(5, 20)), 0.01
    t, k = [], 0.0
    for b in range(int(rng.integers(20, 60))):
        t += [k + dt * j for j in range(burst)]
        k = t[-1] + (float(rng.uniform(1.0, 2.0)) if b == 0 else 3 * dt)
    t = np.round(np.array(t), 6)
    u = np.sin(t)
    y = np.cos(t) + 0.01 * rng.normal(size=t.size)
    p = tmp_path / name
    p.write_text("time_s,voltage_V,displacement_mm\n" + "".join(f"{a:.6f},{b:.6f},{c:.6f}\n" for a, b, c in zip(t, u, y)))
    return p, burst


@pytest.mark.parametrize("seed", SEEDS[:3])
def test_burst_sampling_is_reported_kept_and_resampled(tmp_path, seed):
    p, burst = irregular_csv(tmp_path, seed)
    kept = check_record(load_record(p, irregular="keep"))
    assert [f.kind for f in kept] == ["gap", "irregular_sampling"]
    assert kept[0].action == "cut" and kept[0].index[0] == 0 and kept[1].action == "resample"
    assert f"bursts of {burst} samples" in kept[1].message and "--resample 0.01" in kept[1].message
    res = check_record(load_record(p, resample=0.01))
    assert [f.kind for f in res] == ["gap", "irregular_sampling"] and res[1].action == "mark"
    assert "interpolated, not measured" in res[1].message


# -- across records ------------------------------------------------------------------------------


def family(seed, k=4):
    recs = []
    for j in range(k):
        r, _ = clean(10 * seed + j)
        # one system, one scale: undo the random scale and offset of `clean` by re-generating at unit scale
        rng = np.random.default_rng(10 * seed + j)
        n = len(r)
        u = (r.u - r.u.min()) / np.ptp(r.u)
        y = lag(play(u, 0.08) + 0.4 * play(u, 0.08) ** 2, 0.03) + 0.004 * rng.normal(size=n)
        recs.append(Record.from_arrays(np.arange(n) * 0.01, 200 * u, -7 - 20 * y, name=f"run{j}"))
    return recs


@pytest.mark.parametrize("seed", SEEDS[:4])
def test_run_level_offset_is_found(seed):
    recs = family(seed)
    assert check_records(recs, per_record=False) == []
    rng = np.random.default_rng(6000 + seed)
    j = int(rng.integers(len(recs)))
    d = float(rng.choice([-1, 1]) * rng.uniform(0.5, 3.0) * span(recs[j]))
    recs[j] = with_y(recs[j], recs[j].y + d)
    found = check_records(recs, per_record=False)
    assert [(f.kind, f.record) for f in found] == [("level_mismatch", f"run{j}")]
    assert found[0].size == pytest.approx(d, abs=0.15 * span(recs[0])) and found[0].action == "drop"


@pytest.mark.parametrize("seed", SEEDS[:3])
def test_input_range_mismatch_is_found(seed):
    recs = family(seed)
    rng = np.random.default_rng(7000 + seed)
    j = int(rng.integers(len(recs)))
    r = recs[j]
    recs[j] = Record.from_arrays(r.time, r.u * rng.uniform(0.1, 0.4), r.y, name=r.name)
    found = [f for f in check_records(recs, per_record=False) if f.kind == "input_range"]
    assert [f.record for f in found] == [r.name]
    recs[j] = Record.from_arrays(r.time, r.u * rng.uniform(1.6, 3.0), r.y, name=r.name)
    found = [f for f in check_records(recs, per_record=False) if f.kind == "input_range"]
    assert [f.record for f in found] == [r.name] and "outside" in found[0].message


def test_sample_time_mismatch_and_duplicate_files(tmp_path, datasets_dir):
    for name in ("steps", "main_loop"):
        shutil.copy(datasets_dir / f"{name}.csv", tmp_path / f"{name}.csv")
    shutil.copy(datasets_dir / "steps.csv", tmp_path / "steps_copy.csv")
    recs = load_records(tmp_path)
    found = check_records(recs)
    assert [(f.kind, f.record) for f in found] == [("duplicate", "steps_copy")]
    fast = [Record.from_arrays(r.time / 2, r.u, r.y, name=r.name) for r in recs[:1]]
    found = check_records(fast + recs[1:], per_record=False)
    assert ("dt_mismatch", recs[0].name) in [(f.kind, f.record) for f in found]


def test_finding_serialises_and_prints():
    rec, holds = clean(1)
    y = rec.y.copy()
    y[: holds[0][1] // 2] -= 3 * span(rec)
    f = check_record(with_y(rec, y))[0]
    d = json.loads(json.dumps(f.to_dict()))
    assert d["kind"] == "offset_jump" and d["action"] == "cut" and d["index"] == list(f.index)
    line = f.line("mm")
    assert line.startswith("clean1  offset_jump  [output]") and "mm (" in line and "-> cut:" in line


# -- real data -------------------------------------------------------------------------------------


def test_real_cavatappi_zeroing_is_found_only_where_it_is(real_data):
    files = sorted(real_data.glob("cavatappi_pneumatic_200g_*.csv"))
    recs = load_records(files, input="pressure", output="displacement_mm", resample=0.01)
    found = check_records(recs)
    jumps = [f for f in found if f.kind == "offset_jump"]
    assert [f.record for f in jumps] == ["cavatappi_pneumatic_200g_s1_t2"]
    f = jumps[0]
    assert f.action == "cut" and f.index[0] == 0 and 8.0 < f.time_s[1] < 8.1
    assert -50 < f.size < -40  # the first 8 s read about -52 mm instead of about -7 mm
    assert not any(f.kind == "level_mismatch" for f in found)
    assert all(np.allclose(np.diff(r.time), 0.01) for r in recs)
    # a whole run read 50 mm off is told from the other runs
    recs[2] = Record.from_arrays(recs[2].time, recs[2].u, recs[2].y + 50, name=recs[2].name)
    found = check_records(recs, per_record=False)
    assert [(f.kind, f.record) for f in found] == [("level_mismatch", recs[2].name)] and 40 < found[0].size < 60


def test_real_water_step_rezeroing_is_found(real_data):
    files = sorted(real_data.glob("niti_wire_water_step_*.csv"))
    recs = load_records(files, input="temperature_end_C", output="length_signal")
    jumps = {f.record: f for f in check_records(recs) if f.kind == "offset_jump"}
    assert sorted(jumps) == [f"niti_wire_water_step_0{k}" for k in (2, 3, 4)]
    assert all(f.action == "cut" and f.index[0] == 0 and f.time_s[1] < 10 for f in jumps.values())


# -- the command ---------------------------------------------------------------------------------------


def test_cli_check_prints_findings_and_writes_json(tmp_path, capsys):
    p, _ = irregular_csv(tmp_path, 0)
    assert cli_main(["check", str(p)]) == 0
    out = capsys.readouterr().out
    assert "irregular_sampling" in out and "-> resample" in out and "--resample 0.01" in out
    js = tmp_path / "out.json"
    assert cli_main(["check", str(p), "--resample", "0.01", "--json", str(js)]) == 0
    doc = json.loads(js.read_text())
    assert {f["kind"] for f in doc["findings"]} == {"gap", "irregular_sampling"}
    assert doc["records"][0]["processing"] and doc["records"][0]["dt_s"] == 0.01


def test_cli_check_clean_and_unreadable(tmp_path, datasets_dir, capsys):
    assert cli_main(["check", str(datasets_dir / "steps.csv"), str(datasets_dir / "main_loop.csv")]) == 0
    assert "no findings in 2 record(s)" in capsys.readouterr().out
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,voltage_V,displacement_mm\n0,1,x\n")
    assert cli_main(["check", str(bad)]) == 2
    assert "bad.csv, column 'displacement_mm', row 2: non-numeric value 'x'" in capsys.readouterr().err
    assert cli_main(["check", str(tmp_path / "missing.csv")]) == 2
    assert cli_main(["check", str(datasets_dir / "steps.csv"), "--resample", "fast"]) == 2
