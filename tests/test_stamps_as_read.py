"""A resampled record keeps its stamps as read (`Record.as_read`): the noise estimate and the gap checks use them.

Why: interpolating between jittered stamps averages neighbouring samples, so the noise read on the resampled grid was
0.6-0.9x the truth (every ratio to the noise then read high); and a gap that hides a drive's switching leaves an input
no fit can follow, which only the stamps as read can show.
"""

import dataclasses

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.data import check_record, load_record
from smafl_jax.data.checks import noise_scale, noise_scale_on_stamps


def _write(path, t, u, y):
    path.write_text("time_s,voltage_V,displacement_mm\n" + "".join(f"{a:.6f},{b:.6f},{c:.8f}\n" for a, b, c in zip(t, u, y)))
    return path


def _lagged(u, t, tau=2.0):
    # the plant: a first-order lag on irregular stamps (exact for a held input), one sample at a time
    x = np.zeros_like(u)
    for k in range(1, u.size):
        a = np.exp(-(t[k] - t[k - 1]) / tau)
        x[k] = a * x[k - 1] + (1 - a) * u[k - 1]
    return x


def _stamps(rng, n, dt, jitter, burst=None, gap_steps=0):
    k = np.arange(n, dtype=float)
    if burst:
        k = k + gap_steps * (np.arange(n) // burst)  # gap_steps samples lost after every burst
    return np.round(k * dt + rng.uniform(-jitter, jitter, n) * dt, 6)


def _line_residual_reference(t, x, max_step):
    # plain loop: each sample's distance from the line through its neighbours, scaled to unit noise variance
    r = []
    for k in range(1, t.size - 1):
        d0, d1 = t[k] - t[k - 1], t[k + 1] - t[k]
        if d0 > max_step or d1 > max_step:
            continue
        a = d1 / (d0 + d1)
        r.append((x[k] - a * x[k - 1] - (1 - a) * x[k + 1]) / np.sqrt(1 + a * a + (1 - a) ** 2))
    r = np.array(r)
    return 1.4826 * np.median(np.abs(r - np.median(r)))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_noise_of_a_resampled_jittered_record_is_read_on_its_stamps(tmp_path, seed):
    rng = np.random.default_rng(seed)
    sd, dt = float(rng.uniform(0.002, 0.02)), 0.1
    t = _stamps(rng, 3000, dt, jitter=0.35)
    u = 2.0 + np.sin(2 * np.pi * t / rng.uniform(20, 60)) + 0.5 * np.sin(2 * np.pi * t / rng.uniform(3, 8))
    y = _lagged(u, t) + sd * rng.normal(size=t.size)
    rec = load_record(_write(tmp_path / "jitter.csv", t, u, y), resample=dt)
    assert rec.as_read is not None and rec.as_read.time.size == t.size
    noise = sj.noise_floor(rec)
    assert noise["n_records_on_stamps_as_read"] == 1 and "as read" in noise["method"]
    assert noise["sd"] == pytest.approx(sd, rel=0.12)
    # the grid alone reads it low: what the stamps fix
    grid = sj.noise_floor([dataclasses.replace(rec, as_read=None)])["sd"]
    assert grid < 0.9 * sd
    # an output replaced since the resampling is no longer the stamps' interpolation: the grid is all there is
    moved = dataclasses.replace(rec, y=rec.y + 0.5 * sd * np.sin(rec.time))
    assert sj.noise_floor(moved)["sd"] == pytest.approx(sj.noise_floor([dataclasses.replace(moved, as_read=None)])["sd"])
    # a window keeps the stamps within its span
    win = rec.window(50.0, 200.0)
    assert sj.noise_floor(win)["sd"] == pytest.approx(sd, rel=0.2)


def test_noise_on_stamps_agrees_with_a_loop_and_with_the_grid_rule(tmp_path):
    rng = np.random.default_rng(7)
    t = _stamps(rng, 800, 0.05, jitter=0.3, burst=40, gap_steps=12)
    x = np.cumsum(rng.normal(size=t.size)) * 0.01 + 0.003 * rng.normal(size=t.size)
    got = noise_scale_on_stamps(t, x, max_step=1.5 * 0.05)
    assert got == pytest.approx(_line_residual_reference(t, x, 1.5 * 0.05), rel=1e-12)
    # uniform stamps: the same number as the second-difference rule
    tu = np.arange(500) * 0.01
    assert noise_scale_on_stamps(tu, x[:500], 1.0) == pytest.approx(noise_scale(x[:500]), rel=1e-12)
    # a straight line between jittered stamps has no noise (second differences would see the jitter times the slope)
    line = 3.0 * t
    assert noise_scale_on_stamps(t, line, 1.0) == pytest.approx(0.0, abs=1e-9)
    assert noise_scale(line) > 1e-3


def test_noise_floor_takes_one_array_or_record_alone():
    rng = np.random.default_rng(3)
    y = np.sin(np.arange(2000) * 0.01) + 0.01 * rng.normal(size=2000)
    assert sj.noise_floor(y)["sd"] == sj.noise_floor([y])["sd"]
    with pytest.raises(ValueError, match="1-D array"):
        sj.noise_floor([y.reshape(2, -1)])


def _burst_record(tmp_path, rng, u_of_t, name, burst=20, gap_steps=15, dt=0.1, n=1600, regular=True):
    t = _stamps(rng, n, dt, jitter=0.05, burst=burst, gap_steps=gap_steps if regular else 0)
    if not regular:  # the same number of pauses, at random places and of random lengths
        cuts = np.sort(rng.choice(np.arange(1, n), size=n // burst, replace=False))
        shift = np.zeros(n)
        for c in cuts:
            shift[c:] += rng.uniform(1.5, 4.0) * gap_steps * dt
        t = np.round(t + shift, 6)
    u = u_of_t(t)
    y = _lagged(u, t) + 0.005 * rng.normal(size=t.size)
    return load_record(_write(tmp_path / name, t, u, y), resample=dt)


@pytest.mark.parametrize("seed", [0, 1])
def test_gaps_that_hide_a_pwm_drive_are_found_and_smooth_drives_are_not(tmp_path, seed):
    rng = np.random.default_rng(seed)
    period, duty = float(rng.uniform(1.0, 3.0)), float(rng.uniform(0.3, 0.7))
    pwm = lambda t: np.where((t % period) < duty * period, 3.0, 0.0)
    slow = lambda t: 1.5 + np.sin(2 * np.pi * t / 120.0)
    stairs = lambda t: 0.5 * np.floor(t / 40.0) % 3
    found = [f for f in check_record(_burst_record(tmp_path, rng, pwm, "pwm.csv")) if f.kind == "gap_input"]
    assert len(found) == 1 and found[0].action == "check" and found[0].column == "voltage_V"
    assert "straight line" in found[0].message and found[0].size == pytest.approx(3.0)
    for u_of_t, name in ((slow, "slow.csv"), (stairs, "stairs.csv")):
        assert not [f for f in check_record(_burst_record(tmp_path, rng, u_of_t, name)) if f.kind == "gap_input"], name


def test_a_loggers_rhythm_of_gaps_is_said_once_and_random_pauses_are_listed(tmp_path):
    rng = np.random.default_rng(5)
    slow = lambda t: 1.5 + np.sin(2 * np.pi * t / 120.0)
    rhythm = check_record(_burst_record(tmp_path, rng, slow, "rhythm.csv"))
    assert [f.kind for f in rhythm] == ["irregular_sampling"]
    assert "a logger's rhythm, not listed one by one" in rhythm[0].message
    pauses = check_record(_burst_record(tmp_path, rng, slow, "pauses.csv", regular=False))
    assert sum(f.kind == "gap" for f in pauses) >= 20
    assert "rhythm" not in next(f for f in pauses if f.kind == "irregular_sampling").message
