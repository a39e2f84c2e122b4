"""The fit's errors in units of the output noise SD estimated from the data (`noise_floor`, fit.json metrics.noise)."""

import sys
from pathlib import Path

import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.identify._metrics import ABOVE_NOISE, NOISE_FLOOR_WARN, noise_floor_note  # private: the note's rule

sys.path.insert(0, str(Path(__file__).parent))
import indep_plant as ip


def _signal(rng, n, sd):
    """Smooth motion, steps and white noise of SD ``sd``: a record whose true noise is known."""
    t = np.arange(n) * 0.04
    y = 2.0 * np.sin(0.05 * t) + 0.5 * (np.sin(0.7 * t) > 0) + 0.01 * t
    return y + sd * rng.standard_normal(n)


def test_noise_sd_and_ratios_against_the_true_noise(rng):
    y = _signal(rng, 20000, 0.01)
    train = {"rmse": 0.012}
    nf = sj.noise_floor([y], train=train, validation=None)
    assert nf["sd"] == pytest.approx(0.01, rel=0.05)
    assert nf["train_ratio"] == pytest.approx(0.012 / nf["sd"], rel=1e-12)
    assert nf["validation_ratio"] is None and "per_record_sd" not in nf


def test_several_records_pool_by_samples(rng):
    a, b = _signal(rng, 6000, 0.01), _signal(rng, 2000, 0.04)
    nf = sj.noise_floor([a, b], train={"rmse": 0.03})
    sa, sb = nf["per_record_sd"]
    assert sa == pytest.approx(0.01, rel=0.1) and sb == pytest.approx(0.04, rel=0.1)
    assert nf["sd"] == pytest.approx(np.sqrt((6000 * sa**2 + 2000 * sb**2) / 8000), rel=1e-12)


def test_noise_free_output_gives_no_ratio_and_bad_input_raises():
    nf = sj.noise_floor([np.full(100, 3.0)], train={"rmse": 0.1})
    assert nf["sd"] == 0.0 and nf["train_ratio"] is None and noise_floor_note(nf) is None
    with pytest.raises(ValueError, match="at least one"):
        sj.noise_floor([], train={"rmse": 0.1})


def test_note_only_above_the_warning_level():
    assert noise_floor_note({"sd": 0.01, "train_ratio": NOISE_FLOOR_WARN}) is None
    note = noise_floor_note({"sd": 0.01, "train_ratio": 7.4})
    assert note.startswith(ABOVE_NOISE) and "7.4x" in note


def test_estimate_on_independent_plant_records():
    # plain-numpy plant (no smafl_jax code): every drive family, its own noise level, sensor and quantisation
    for i, fam in enumerate(ip.FAMILIES):
        r = ip.make_record(300 + i, drive=fam, rate_hz=10.0, minutes=5.0)
        ratio = sj.noise_floor([r["y"]])["sd"] / r["noise_sd"]
        assert 0.8 < ratio < 1.25, (fam, ratio)
