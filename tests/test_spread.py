"""`sweep_spread`: how far two fits part on sweeps of the trained input range after the record."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

import smafl_jax as sj
from smafl_jax.identify._spread import SWEEPS, sweep_drive, sweep_spread  # private: the fit's internal probe


def _eupi(rng):
    m = sj.EUPI.from_range(0.0, 7.4, n_sym=3, n_alpha=2, n_asym=2)
    return m.with_linear_weights(jnp.asarray(rng.uniform(0.1, 1.0, m.linear_weights().shape[0])))


def test_the_sweep_spans_the_input_range_in_triangles(rng):
    u = rng.uniform(1.0, 6.0, 200)
    s = sweep_drive(u, 600)
    assert s.shape == (600,)
    assert np.isclose(s.min(), u.min()) and np.isclose(s.max(), u.max(), atol=(u.max() - u.min()) * SWEEPS / 300)
    # SWEEPS rises and SWEEPS falls: the direction changes 2 * SWEEPS - 1 times
    assert np.count_nonzero(np.diff(np.sign(np.diff(s))) != 0) == 2 * SWEEPS - 1


def test_memory_the_record_wipes_out_leaves_no_spread_and_gains_do(rng):
    m = _eupi(rng)
    a, b = m.with_fitted_memory(-3.0), m.with_fitted_memory(3.0)
    # up and down well beyond the operators' thresholds (the grid is for [0, 7.4]), then inside
    u = np.concatenate([np.linspace(3.7, 20.0, 50), np.linspace(20.0, -15.0, 100), rng.uniform(1.0, 6.0, 150)])
    # the two start states differ, so the record's first samples differ ...
    assert np.max(np.abs(np.asarray(a.simulate(u[:20])) - np.asarray(b.simulate(u[:20])))) > 1e-3
    # ... but the record sets every operator: nothing is left open after it
    assert sweep_spread(a, b, u, 0.1)["rms"] < 1e-9
    c = a.with_linear_weights(a.linear_weights() * 1.1)
    got = sweep_spread(a, c, u, 0.1)
    probe = np.concatenate([u, sweep_drive(u, u.size)])
    d = np.asarray(a.simulate(probe))[u.size :] - np.asarray(c.simulate(probe))[u.size :]
    assert np.isclose(got["rms"], np.sqrt(np.mean(d**2))) and np.isclose(got["max"], np.max(np.abs(d)))
    assert got["rms"] > 0 and got["samples"] == u.size and got["sweeps"] == SWEEPS
