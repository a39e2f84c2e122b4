"""play_weighted: fused weighted sum of a play-operator bank (issue 8 speed-up)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from reference import play_loop, random_reversals

from smafl_jax.models import play_weighted


@pytest.mark.parametrize("y0", [None, "random"])
def test_play_weighted_matches_numpy_loop(rng, y0):
    u = random_reversals(rng, 500)
    r = np.sort(rng.uniform(0, 2.0, 7))
    a = rng.uniform(0.3, 3.0, 7)
    w = rng.normal(size=7)
    y0v = rng.uniform(-1, 3, 7) if y0 == "random" else None
    ref = play_loop(u, r, a, 0.0 if y0v is None else y0v) @ w
    got = np.asarray(play_weighted(u, r, a, w, y0=y0v))
    assert got.shape == (500,)
    assert np.max(np.abs(got - ref)) < 1e-11


def test_play_weighted_grad_matches_finite_differences(rng):
    u = random_reversals(rng, 150)
    r = jnp.array([0.1, 0.4, 0.8])

    def f(w, a):
        return jnp.sum(play_weighted(u, r, a, w) ** 2)

    w0, a0 = jnp.array([0.5, 1.0, 0.3]), jnp.array([0.7, 1.2, 1.9])
    gw, ga = jax.grad(f, argnums=(0, 1))(w0, a0)
    h = 1e-6
    for i in range(3):
        e = jnp.zeros(3).at[i].set(h)
        assert abs(gw[i] - (f(w0 + e, a0) - f(w0 - e, a0)) / (2 * h)) < 1e-5 * max(1.0, abs(gw[i]))
        assert abs(ga[i] - (f(w0, a0 + e) - f(w0, a0 - e)) / (2 * h)) < 1e-5 * max(1.0, abs(ga[i]))


def test_play_weighted_vmap_and_bad_weights(rng):
    u = np.stack([random_reversals(rng, 200) for _ in range(4)])
    r, a, w = jnp.array([0.1, 0.3]), 1.5, jnp.array([1.0, 2.0])
    out = jax.vmap(lambda x: play_weighted(x, r, a, w))(u)
    assert out.shape == (4, 200)
    with pytest.raises(ValueError, match="one entry per operator"):
        play_weighted(u[0], r, a, jnp.ones(3))
