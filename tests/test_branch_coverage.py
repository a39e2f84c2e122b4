"""Validation coverage on the hysteresis input's branches (`smafl_jax.data.branch_coverage`) and its use in `fit_record`."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.data import branch_coverage
from smafl_jax.data.split import branch_directions  # private: the branch rule itself, checked against a hand-made signal
from smafl_jax.diagnosis import make_split, split_coverage, state_coverage
from smafl_jax.report._report_fit import _validation_coverage  # private: the rule fit_record applies


def _heat_then_cool(n=1200, ripple=0.004):
    """A thermal-like state: rises for 70 % of the samples, falls after, with a PWM-like ripple on it."""
    k = np.arange(n)
    cut = int(0.7 * n)
    base = np.where(k < cut, k / cut, 1.0 - 0.8 * (k - cut) / (n - cut))
    return base + ripple * np.sign(np.sin(2 * np.pi * k / 8)), cut


def _numpy_branch_directions(x, deadband):
    """Reference: one sample at a time, the band [lo, hi] of width 2 deadband follows x when x leaves it."""
    out = np.zeros(x.size, int)
    lo, hi, d = x[0] - deadband, x[0] + deadband, 0
    for i, v in enumerate(x):
        if v > hi:
            hi, lo, d = v, v - 2.0 * deadband, 1
        elif v < lo:
            lo, hi, d = v, v + 2.0 * deadband, -1
        out[i] = d
    return out


def test_branch_directions_match_a_numpy_loop():
    x = np.cumsum(np.random.default_rng(3).standard_normal(3000))
    for deadband in (0.3, 1.5, 10.0):
        np.testing.assert_array_equal(branch_directions(x, deadband), _numpy_branch_directions(x, deadband))


def test_branch_directions_follow_the_slow_state_not_its_ripple():
    x, cut = _heat_then_cool()
    d = branch_directions(x, deadband=0.02)
    assert d[0] == 0  # before the first move larger than the deadband
    assert np.all(d[30 : cut - 5] == 1) and np.all(d[cut + 40 :] == -1)
    # a slope rule flips on every ripple period; the branch rule never does inside one branch
    slope = np.sign(np.diff(x))
    assert np.sum(slope[30 : cut - 5] < 0) > 50


def test_validation_on_an_untrained_branch_is_flagged_and_a_trained_one_is_not():
    x, cut = _heat_then_cool()
    train = np.arange(x.size) < cut
    cov = branch_coverage(x, train, ~train, what="thermal state")
    assert cov["covered_fraction"] < 0.1 and cov["by_direction"]["falling"]["covered"] == 0.0
    assert "untrained branch" in cov["warning"] and "thermal state" in cov["warning"]
    # the same levels falling in training too (interleaved blocks): covered
    blocks = (np.arange(x.size) // 8) % 4 != 3
    cov = branch_coverage(x, blocks, ~blocks)
    assert cov["covered_fraction"] > 0.9 and "warning" not in cov


def test_branch_coverage_rejects_mismatched_masks():
    with pytest.raises(sj.UserInputError, match="one shape"):
        branch_coverage(np.zeros(10), np.ones(10, bool), np.ones(9, bool))


def test_fit_coverage_uses_the_thermal_state_a_pwm_voltage_hides():
    """A PWM drive whose duty rises through training and falls after: its voltage switches both ways every period (the
    input-level coverage sees every branch), but the thermal state the hysteresis sees only cools in validation."""
    dt, n = 0.1, 900
    k = np.arange(n)
    duty = np.where(k < 630, 0.1 + 0.8 * k / 630, 0.9 - 0.8 * (k - 630) / 270)
    u = 3.0 * ((k % 10) < 10 * duty)
    small = dict(n_sym=3, n_alpha=2, n_asym=2, poly_order=2)
    truth = sj.Cascade.from_range(3.0, thermal=sj.JouleThermal(k1=jnp.asarray(0.05)), **small)
    truth = eqx.tree_at(lambda m: m.hysteresis, truth, truth.hysteresis.with_linear_weights(np.linspace(0.1, 0.5, 10)))
    y = np.asarray(sj.simulate(truth, u, dt))
    rec = sj.Record.from_arrays(dt * k, u, y + 0.001 * np.random.default_rng(0).standard_normal(n), input_name="voltage_V")
    assert sj.data.coverage(sj.data.time_block(rec, 0.3))["covered_fraction"] > 0.9  # the drive voltage: "covered"
    train = k < 630
    cov = _validation_coverage(truth, rec, train, ~train)  # what fit_record stores in fit.json split.coverage
    assert cov["covered_fraction"] < 0.9 and "thermal state" in cov["signal"] and "untrained branch" in cov["warning"]
    # the diagnosis: its time-block split is kept (the voltage "covers"), and diagnosis.json split.state_coverage says so
    split = make_split(rec)
    assert split.kind == "time" and split_coverage(split)["covered_fraction"] > 0.9
    state = state_coverage(truth, split)
    assert state["covered_fraction"] == pytest.approx(cov["covered_fraction"]) and "untrained branch" in state["warning"]
    assert state_coverage(truth.hysteresis, split) is None  # no thermal stage: the input check is the one
    # a model that sees its input directly is checked on that input
    cov = _validation_coverage(truth.hysteresis, rec, train, ~train)
    assert cov["signal"] == "input 'voltage_V'"
