import jax
import jax.numpy as jnp
import numpy as np
import pytest
from reference import play_loop, random_reversals

import smafl_jax as sj


@pytest.mark.parametrize("alpha", [1.0, 0.4, 2.5, "mixed"])
@pytest.mark.parametrize("y0", [0.0, "random"])
def test_play_matches_numpy_loop(rng, alpha, y0):
    u = random_reversals(rng, 700)
    r = np.sort(rng.uniform(0, 2.0, 9))
    a = rng.uniform(0.3, 3.0, 9) if alpha == "mixed" else alpha
    y0v = rng.uniform(-1, 3, 9) if y0 == "random" else y0
    ref = play_loop(u, r, a, y0v)
    for method in ("scan", "assoc"):
        got = np.asarray(sj.play(u, r, a, y0=y0v, method=method))
        assert got.shape == (700, 9)
        assert np.max(np.abs(got - ref)) < 1e-12, method


def test_assoc_equals_scan_long_record(rng):
    u = random_reversals(rng, 20_000, n_knots=200)
    r = np.linspace(0.05, 2.0, 16)
    a = np.linspace(0.5, 2.0, 16)
    np.testing.assert_array_equal(np.asarray(sj.play_scan(u, r, a)), np.asarray(sj.play_assoc(u, r, a)))


def test_symmetric_play_is_backlash():
    # Hand-checked: threshold 1, input 0 -> 3 -> 1 -> 2.
    u = np.array([0.0, 3.0, 1.0, 2.0])
    y = np.asarray(sj.play(u, [1.0]))[:, 0]
    np.testing.assert_allclose(y, [0.0, 2.0, 2.0, 2.0])
    u = np.array([0.0, 3.0, 0.5])
    np.testing.assert_allclose(np.asarray(sj.play(u, [1.0]))[:, 0], [0.0, 2.0, 1.5])


def test_zero_threshold_is_identity_for_symmetric(rng):
    u = random_reversals(rng, 200)
    np.testing.assert_allclose(np.asarray(sj.play(u, [0.0]))[:, 0], u, atol=0, rtol=0)


def test_vmap_over_inputs_shapes(rng):
    u = np.stack([random_reversals(rng, 300) for _ in range(5)])
    out = jax.vmap(lambda x: sj.play_scan(x, jnp.array([0.1, 0.3, 0.5]), 1.5))(u)
    assert out.shape == (5, 300, 3)
    out2 = jax.vmap(lambda x: sj.play_assoc(x, jnp.array([0.1, 0.3, 0.5]), 1.5))(u)
    np.testing.assert_array_equal(np.asarray(out), np.asarray(out2))


def test_bad_shapes_raise():
    with pytest.raises(ValueError, match="1-D input"):
        sj.play(np.zeros((3, 4)), [0.1])
    with pytest.raises(ValueError, match="method"):
        sj.play(np.zeros(4), [0.1], method="fast")


def test_grad_through_play_matches_finite_differences(rng):
    u = random_reversals(rng, 120)
    r = jnp.array([0.2, 0.6])

    def f(a):
        return jnp.sum(sj.play_scan(u, r, a) ** 2)

    a0 = 1.3
    g = jax.grad(f)(a0)
    h = 1e-6
    fd = (f(a0 + h) - f(a0 - h)) / (2 * h)
    assert abs(g - fd) < 1e-5 * max(1.0, abs(fd))
