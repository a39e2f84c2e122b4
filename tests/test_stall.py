"""`StallStop`: the log-likelihood stall rule against a numpy loop over the plain solver's losses, identical iterates,
one trace, bad settings."""

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest

from smafl_jax.identify import STALL_MIN_GAIN, STALL_WINDOW, StallStop

# two nearly equal decay rates: Levenberg-Marquardt crawls along the valley for hundreds of steps (388 here) while the
# loss stops changing after a few dozen
T = jnp.linspace(0.0, 1.0, 400)
Y = 2.0 * jnp.exp(-3.0 * T) + 0.5 * jnp.exp(-3.6 * T) + 0.01 * jnp.asarray(np.random.default_rng(0).standard_normal(400))
P0 = jnp.array([1.0, 1.0, 1.0, 8.0])


def residuals(p, y):
    return p[0] * jnp.exp(-p[1] * T) + p[2] * jnp.exp(-p[3] * T) - y


def lm(**kw):
    return optx.LevenbergMarquardt(rtol=1e-10, atol=1e-12, **kw)


def numpy_stop(half_sse, n, window, min_gain):
    """Step count at which the rule stops, from the plain solve's accepted losses (half_sse[j]: after j steps)."""
    for j in range(window + 1, len(half_sse)):
        if 0.5 * n * np.log(half_sse[j - window] / half_sse[j]) < min_gain:
            return j
    return None


def test_stall_rule_matches_numpy_loop_and_keeps_the_plain_iterates():
    seen = []

    def record(**kw):
        jax.debug.callback(lambda v: seen.append(float(v)), kw["loss_last_accepted_step"][1])

    plain = optx.least_squares(residuals, lm(verbose=record), P0, Y, max_steps=2000, throw=False)
    stalled = optx.least_squares(residuals, StallStop(lm()), P0, Y, max_steps=2000, throw=False)
    expected = numpy_stop(np.array(seen), Y.size, STALL_WINDOW, STALL_MIN_GAIN)
    assert expected is not None and expected < int(plain.stats["num_steps"]) // 4
    assert int(stalled.stats["num_steps"]) == expected
    assert bool(stalled.stats["stalled"])
    # the wrapper only decides when to stop: the point is the one the plain solver reaches in that many steps
    cut = optx.least_squares(residuals, lm(), P0, Y, max_steps=expected, throw=False)
    np.testing.assert_array_equal(np.asarray(stalled.value), np.asarray(cut.value))


def test_stall_never_fires_with_zero_gain_and_a_solve_that_converges_is_untouched():
    plain = optx.least_squares(residuals, lm(), P0, Y, max_steps=2000, throw=False)
    never = optx.least_squares(residuals, StallStop(lm(), min_gain=0.0), P0, Y, max_steps=2000, throw=False)
    assert int(never.stats["num_steps"]) == int(plain.stats["num_steps"])
    assert not bool(never.stats["stalled"])
    np.testing.assert_array_equal(np.asarray(never.value), np.asarray(plain.value))


def test_stall_solve_traces_once():
    traces = []

    @jax.jit
    def solve(y):
        traces.append(1)
        return optx.least_squares(residuals, StallStop(lm()), P0, y, max_steps=500, throw=False).value

    solve(Y)
    solve(Y * 1.01)
    assert len(traces) == 1


@pytest.mark.parametrize("kw", [{"window": 0}, {"window": 2.5}, {"min_gain": -1.0}])
def test_stall_bad_settings(kw):
    with pytest.raises(ValueError, match="StallStop"):
        StallStop(lm(), **kw)
