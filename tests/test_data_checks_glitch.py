"""Data checks: multi-second glitch blocks, the robust cross-record input range, and rest vs clipping.

A glitch block is a stretch of seconds at an implausible level, entered and left by jumps (a thermocouple reading
86-220 C while the wire is at 27-60 C, as in niti_wire_electric_04).  It must be found where planted, while the
drives a rig really uses (steps, PWM, multisines from the independent plant) give none.
"""

import numpy as np
import pytest

from smafl_jax.data import Record, check_record, check_records, load_record, load_records
from smafl_jax.data.checks import _glitches  # private: the detector on a column the record treats as a drive voltage

SEEDS = range(4)


def heated_wire(seed, n=600, dt=0.1):
    """A NiTi wire heated in pulses: front thermocouple (input, C) with a first-order lag and noise, and a
    contraction that follows it through a smooth S-curve (output)."""
    rng = np.random.default_rng(seed)
    power = np.zeros(n)
    k = int(rng.integers(30, 60))
    while k < n - 40:
        on = int(rng.integers(40, 120))
        power[k : k + on] = rng.uniform(0.5, 1.0)
        k += on + int(rng.integers(40, 120))
    temp = np.empty(n)
    temp[0] = 26.0
    for i in range(1, n):
        temp[i] = temp[i - 1] + 0.08 * (26.0 + 40.0 * power[i - 1] - temp[i - 1])
    y = 15.0 / (1.0 + np.exp(-(temp - 45.0) / 3.0)) + 0.02 * rng.normal(size=n)
    temp = temp + 0.3 * rng.normal(size=n)
    return np.arange(n) * dt, temp, y


def record(t, u, y, name="wire"):
    return Record.from_arrays(t, u, y, name=name, input_name="temperature_front_C", output_name="length_signal")


def plant_glitch(u, a, length, rng):
    """Samples ``a .. a+length-1`` of ``u`` replaced by an erratic reading far above the record's range (a loose
    thermocouple: 2-sample pairs at 100-220 C, as the real one reads)."""
    u = u.copy()
    hi = float(u.max())
    pairs = np.repeat(hi + rng.uniform(40, 160, size=(length + 1) // 2), 2)[:length]
    u[a : a + length] = pairs + 0.3 * rng.normal(size=length)
    return u


# -- found where planted --------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", SEEDS)
def test_glitch_block_is_found_with_its_start_end_and_size(seed):
    t, u, y = heated_wire(seed)
    assert check_record(record(t, u, y)) == []
    rng = np.random.default_rng(100 + seed)
    a, length = int(rng.integers(150, 400)), 50  # 5 s at 10 Hz, away from both ends
    bad = plant_glitch(u, a, length, rng)
    found = check_record(record(t, bad, y))
    assert [(f.kind, f.column, f.index, f.action) for f in found] == [("glitch", "temperature_front_C", (a, a + length), "mark")]
    f = found[0]
    assert "erratic" in f.message
    assert f.time_s == (pytest.approx(t[a]), pytest.approx(t[a + length - 1]))
    level = float(np.median(bad[a : a + length]))
    sides = [float(np.median(u[a - 10 : a])), float(np.median(u[a + length : a + length + 10]))]
    assert f.size == pytest.approx(level - min(sides, key=lambda s: abs(level - s)), rel=0.02) and f.size > 0
    assert f"{length} samples" in f.message


def test_glitch_block_near_the_start_is_cut_and_its_spikes_are_not_listed():
    t, u, y = heated_wire(7)
    rng = np.random.default_rng(7)
    a, length = 15, 55
    bad = plant_glitch(u, a, length, rng)
    bad[a + 20 : a + 22] += 150  # a 2-sample excursion inside the block: part of the glitch, not a spike of its own
    found = check_record(record(t, bad, y))
    assert [(f.kind, f.index, f.action) for f in found] == [("glitch", (a, a + length), "cut")]
    assert f"--window {t[a + length]:.6g}:" in found[0].message


def test_low_level_glitch_on_the_output_is_found():
    """The output reading a stretch far below anything it reads otherwise, while the input moves smoothly."""
    t, u, y = heated_wire(3)
    y = y + 5.0  # the sensor reads 5 .. 20
    a, length = 300, 40
    y[a : a + length] = -30.0 + 0.5 * np.random.default_rng(3).normal(size=length)
    found = [f for f in check_record(record(t, u, y)) if f.kind == "glitch"]
    assert [(f.column, f.index) for f in found] == [("length_signal", (a, a + length))] and found[0].size < 0


# -- not a glitch ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("drive", ["steps", "pwm", "multisine", "staircase"])
def test_independent_plant_drives_give_no_glitch(drive):
    import indep_plant

    for seed in (0, 1):
        r = indep_plant.make_record(seed, drive=drive, rate_hz=10, minutes=5)
        rec = Record.from_arrays(r["time"], r["u"], r["y"], name=drive, input_name="voltage_V", output_name="displacement_mm")
        assert not [f for f in check_record(rec) if f.kind == "glitch"], (drive, seed)
        if drive in ("pwm", "multisine"):
            # read as a measured column, too: PWM pulses are many and at a level the drive dwells at
            assert _glitches(rec, np.asarray(r["u"], float), "as_measured", 0.15) == [], (drive, seed)


def test_a_drive_voltage_is_not_searched():
    """One 5 V pulse of 60 s from a supply that ripples under load, in a 10-minute record: as a measured reading that
    would be a glitch block (beyond the rest, entered and left by jumps, rougher than the clean 0 V), as a commanded
    drive it is a step test."""
    rng = np.random.default_rng(4)
    n = 1200
    u = np.zeros(n)
    u[500:620] = 5.0 + 0.1 * rng.normal(size=120)
    y = np.empty(n)
    y[0] = 0.0
    for i in range(1, n):
        y[i] = y[i - 1] + 0.02 * (0.4 * u[i - 1] ** 2 - y[i - 1])  # a thermal lag: the output cannot jump
    y = y + 0.01 * rng.normal(size=n)
    rec = Record.from_arrays(np.arange(n) * 0.5, u, y, name="pulse", input_name="voltage_V", output_name="displacement_mm")
    assert [f.index for f in _glitches(rec, u, "as_measured", 0.15)] == [(500, 620)]
    assert check_record(rec) == []


def test_a_heating_pulse_read_by_the_thermocouple_is_no_glitch():
    """A fast thermocouple on a thin wire: one 6 s pulse 26 -> 60 C, reached within a sample, in a minute at ambient;
    beyond everything else and entered and left by jumps, but read with the sensor's own noise: driven, not faulty."""
    rng = np.random.default_rng(8)
    n = 600
    temp = np.full(n, 26.0)
    temp[300:360] = 60.0
    temp = temp + 0.3 * rng.normal(size=n)
    y = 15.0 / (1.0 + np.exp(-(temp - 45.0) / 3.0)) + 0.02 * rng.normal(size=n)
    assert not [f for f in check_record(record(np.arange(n) * 0.1, temp, y)) if f.kind == "glitch"]


def test_a_frozen_reading_at_an_implausible_level_is_found():
    """An open thermocouple: the front reads a constant 350 C for 6 s (frozen, unlike the noisy sensor)."""
    t, u, y = heated_wire(5)
    a, length = 250, 60
    bad = u.copy()
    bad[a : a + length] = 350.0
    found = check_record(record(t, bad, y))
    assert [(f.kind, f.index) for f in found] == [("glitch", (a, a + length))] and "frozen" in found[0].message


def test_a_fast_output_that_follows_an_input_pulse_is_no_glitch():
    rng = np.random.default_rng(11)
    n = 800
    u = np.zeros(n)
    u[300:360] = 5.0  # one pressure pulse through a fast valve
    y = -8.0 * u + 0.05 * rng.normal(size=n)
    rec = Record.from_arrays(np.arange(n) * 0.01, u + 0.01 * rng.normal(size=n), y, name="fast", input_name="pressure")
    assert not [f for f in check_record(rec) if f.kind == "glitch" and f.column == "output"]


# -- across records ----------------------------------------------------------------------------------------


def test_two_faulty_records_do_not_hide_each_other_in_the_input_range_check():
    # six records: two faulty ones among five others leave the others' median span (the span rule) a clean one
    recs = [record(*heated_wire(20 + j), name=f"run{j}") for j in range(6)]
    assert not [f for f in check_records(recs, per_record=False) if f.kind == "input_range"]
    rng = np.random.default_rng(5)
    for j in (1, 3):  # both read far too high for 12-15 % of the record, the union of the others covers either
        t, u, y = recs[j].time, recs[j].u, recs[j].y
        recs[j] = record(t, plant_glitch(u, 200, int(rng.integers(75, 90)), rng), y, name=f"run{j}")
    found = [f for f in check_records(recs, per_record=False) if f.kind == "input_range"]
    assert sorted(f.record for f in found) == ["run1", "run3"]
    assert {f.record for f in check_records(recs) if f.kind == "glitch"} == {"run1", "run3"}


# -- rest is not clipping ---------------------------------------------------------------------------------------


def forc_record(clip_at=None):
    """An SMA wire voltage record: exactly 0 output below its activation voltage (at rest), a saturating rise above."""
    rng = np.random.default_rng(2)
    branches = [np.concatenate([np.linspace(0, top, 100), np.linspace(top, 0, 100)]) for top in rng.uniform(2.4, 3.5, 8)]
    u = np.concatenate(branches)
    y = np.clip(16 * np.tanh(np.clip(u - 1.8, 0, None)), 0, None)
    y = np.where(y > 0, y + 0.05 * rng.normal(size=u.size), 0.0)
    y = np.maximum(y, 0.0)
    if clip_at is not None:
        y = np.minimum(y, clip_at)
    return Record.from_arrays(np.arange(u.size) * 1.0, u, y, name="forc", input_name="voltage_V", output_name="displacement")


def test_output_at_rest_is_not_clipped_but_a_clip_at_the_top_is():
    assert check_record(forc_record()) == []
    rec = forc_record(clip_at=12.0)
    found = [f for f in check_record(rec) if f.kind == "clipped"]
    assert len(found) == 1 and "maximum 12" in found[0].message


def test_real_sma_wing_rest_is_not_clipped_and_niti_glitches_are_found(real_data):
    assert not [f for f in check_record(load_record(real_data / "sma_wing_forc_train.csv")) if f.kind == "clipped"]
    files = sorted(real_data.glob("niti_wire_electric_0*.csv"))
    recs = load_records(files, input="temperature_front_C", output="length_signal")
    found = {f.record: f for f in check_records(recs) if f.kind == "glitch"}
    assert sorted(found) == ["niti_wire_electric_04", "niti_wire_electric_05"]
    f4, f5 = found["niti_wire_electric_04"], found["niti_wire_electric_05"]
    assert 1.3 < f4.time_s[0] < 1.5 and 6.8 < f4.time_s[1] < 7.0 and f4.action == "cut" and f4.size > 30
    assert 11.7 < f5.time_s[0] < 11.9 and 16.0 < f5.time_s[1] < 16.4 and f5.size > 20
