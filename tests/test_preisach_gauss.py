"""GaussianPreisach: the relay bank against a plain numpy loop, gradients, recovery, the start from a screened grid."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax import GaussianPreisach, Preisach


def _numpy_reference(u, lo_ref, span, n, shape, scale, gain, offset, init_up, orientation=1, extend=0.0):
    """Plain numpy: ramp relays one cell wide on cell-centred levels over the range widened by ``extend`` of it at each
    end, Gaussian weights in loop centre and width (in units of the range itself)."""
    h = span * (1 + 2 * extend) / n
    lv = lo_ref - extend * span + (np.arange(n) + 0.5) * h
    i, j = np.tril_indices(n)
    a, b = lv[i], lv[j]
    c, d = ((a + b) / 2 - lo_ref) / span, (a - b) / span
    floor = 0.5 * (1 + 2 * extend) / n
    zc = (c - shape["centre"]) / (shape["centre_sd"] + floor)
    zd = (d - shape["loop"]) / (shape["loop_sd"] + floor)
    r = math.tanh(shape["corr"])
    q = (zc**2 - 2 * r * zc * zd + zd**2) / (2 * (1 - r * r))
    rho = np.exp(-(q - q.min()))
    rho /= rho.sum()
    state = np.ones(a.size) if init_up else np.zeros(a.size)
    out = []
    for x in u:
        for m in range(a.size):
            up = min(max((x - a[m]) / h + 0.5, 0.0), 1.0)
            allowed = min(max((x - b[m]) / h + 0.5, 0.0), 1.0)
            state[m] = max(min(state[m], allowed), up)
        out.append(orientation * scale * (state @ rho) + gain * (x - lo_ref) / span + offset)
    return np.array(out)


SHAPE = dict(centre=0.55, centre_sd=0.12, loop=0.3, loop_sd=0.1, corr=0.4)


def _model(n=10, init="descended", orientation=1, extend=0.0, **shape):
    m = GaussianPreisach.from_range(1.0, 3.0, n_levels=n, init=init, orientation=orientation, extend=extend)
    m = m.with_linear_weights(jnp.array([2.0, 0.3, -0.5]))
    return eqx_replace(m, **{**SHAPE, **shape})


def eqx_replace(m, **fields):
    import dataclasses

    return dataclasses.replace(m, **{k: jnp.asarray(v, dtype=jnp.float64) for k, v in fields.items()})


def _input(rng, n=160):
    # rises, falls to an inner minimum, rises again part-way (a first-order reversal), with noise
    base = np.r_[
        np.linspace(1.0, 3.0, n // 4), np.linspace(3.0, 1.6, n // 4), np.linspace(1.6, 2.6, n // 4), np.linspace(2.6, 1.2, n // 4)
    ]
    return base + 0.02 * rng.standard_normal(base.size)


@pytest.mark.parametrize("init", ["descended", "zero"])
@pytest.mark.parametrize("orientation, extend", [(1, 0.0), (-1, 0.0), (1, 0.25)])
def test_matches_plain_numpy_loop(rng, init, orientation, extend):
    u = _input(rng)
    if extend:  # an input beyond the range, into the extended grid and past it
        u = np.r_[u, np.linspace(1.2, 3.7, 40), np.linspace(3.7, 0.4, 40)]
    m = _model(init=init, orientation=orientation, extend=extend)
    ref = _numpy_reference(u, 1.0, 2.0, 10, SHAPE, 2.0, 0.3, -0.5, init == "descended", orientation, extend)
    np.testing.assert_allclose(np.asarray(m.simulate(u)), ref, atol=1e-12)
    _, y = jax.lax.scan(lambda s, x: m.step(s, x), m.initial_state(u[0]), jnp.asarray(u))
    np.testing.assert_allclose(np.asarray(y), ref, atol=1e-12)


def test_shape_gradient_matches_finite_differences(rng):
    u = jnp.asarray(_input(rng))
    y = jnp.asarray(_numpy_reference(np.asarray(u), 1.0, 2.0, 10, dict(SHAPE, centre=0.5, loop=0.25), 2.0, 0.3, -0.5, True))
    names = ("centre", "centre_sd", "loop", "loop_sd", "corr")

    def loss(v):
        m = _model(**dict(zip(names, v)))
        return jnp.sum((m.simulate(u) - y) ** 2)

    v0 = jnp.array([SHAPE[k] for k in names])
    g = np.asarray(jax.grad(loss)(v0))
    eps = 1e-6
    fd = [(float(loss(v0.at[k].add(eps))) - float(loss(v0.at[k].add(-eps)))) / (2 * eps) for k in range(len(names))]
    np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-7)


@pytest.mark.slow  # suite time (session 71: 15 s under load); the shape gradient against finite differences stays in the default suite
def test_recovers_shape_from_a_record_of_its_own_class(rng):
    u = np.concatenate([_input(rng, 200), _input(rng, 200)[::-1]])
    truth = _model(n=12)
    y = np.asarray(truth.simulate(u)) + 1e-3 * rng.standard_normal(u.size)
    start = eqx_replace(_model(n=12), centre=0.5, centre_sd=0.2, loop=0.2, loop_sd=0.2, corr=0.0)
    res = sj.fit(start, (u, y), 1.0, max_steps=200)
    got = res.model
    rms = float(np.sqrt(np.mean((np.asarray(got.simulate(u)) - y) ** 2)))
    assert rms < 2e-3  # the noise level
    for k in ("centre", "loop"):
        assert float(getattr(got, k)) == pytest.approx(SHAPE[k], abs=0.03)


def test_adopt_takes_the_screened_grids_moments_and_rule(rng):
    # a free relay grid whose weights are a Gaussian of known moments: the first start carries them over
    screened = Preisach.from_range(1.0, 3.0, n_levels=20, init="zero", orientation=-1)
    a, b = (np.asarray(t) for t in screened.thresholds())
    c, d = ((a + b) / 2 - 1.0) / 2.0, (a - b) / 2.0
    w = np.where(a > b, np.exp(-0.5 * (((c - 0.6) / 0.1) ** 2 + ((d - 0.3) / 0.08) ** 2)), 0.0)
    screened = screened.with_linear_weights(jnp.asarray(np.r_[w, 0.0]))
    starts = GaussianPreisach.from_range(0.0, 1.0).adopt(screened)
    first = starts[0]
    assert len(starts) > 1 and all(s.init == "zero" and s.orientation == -1 for s in starts)
    assert float(first.u_ref) == 1.0 and float(first.u_span) == 2.0  # the screened range (a cascade may rescale it)
    assert float(first.centre) == pytest.approx(0.6, abs=0.02) and float(first.loop) == pytest.approx(0.3, abs=0.03)
    assert float(first.centre_sd) == pytest.approx(0.1, abs=0.03)


def test_batches_under_vmap(rng):
    m = _model()
    u = jnp.asarray(np.stack([_input(rng) for _ in range(3)]))
    y = jax.vmap(m.simulate)(u)
    assert y.shape == u.shape
    np.testing.assert_allclose(np.asarray(y[1]), np.asarray(m.simulate(u[1])), atol=1e-13)


def test_bad_construction_is_refused():
    with pytest.raises(ValueError, match="u_max > u_min"):
        GaussianPreisach.from_range(2.0, 1.0)
    with pytest.raises(ValueError, match="n_levels"):
        GaussianPreisach.from_range(0.0, 1.0, n_levels=1)
    with pytest.raises(ValueError, match="orientation"):
        GaussianPreisach.from_range(0.0, 1.0, orientation=2)
    with pytest.raises(ValueError, match="init"):
        GaussianPreisach.from_range(0.0, 1.0, init="from_top")
    with pytest.raises(ValueError, match="3 linear weights"):
        GaussianPreisach.from_range(0.0, 1.0).with_linear_weights(jnp.zeros(4))


def test_grid_reaches_beyond_the_range_and_old_files_load():
    """A grid extended by ``extend`` of the range beyond each end keeps the shape in units of the range; the default is
    `EXTEND`; a model saved before the field existed (no ``extend`` key) loads with its own grid and extend 0."""
    assert GaussianPreisach.from_range(1.0, 3.0).extend == GaussianPreisach.EXTEND
    e = 0.2
    m = GaussianPreisach.from_range(1.0, 3.0, n_levels=20, extend=e)
    assert m.extend == e and m.n_levels == 20
    lv = np.asarray(m.levels)
    cell = 2.0 * (1 + 2 * e) / m.n_levels
    np.testing.assert_allclose([lv[0], lv[-1]], [1.0 - 2.0 * e + cell / 2, 3.0 + 2.0 * e - cell / 2])
    assert float(m.u_ref) == 1.0 and float(m.u_span) == 2.0 and float(m.ramp) == pytest.approx(cell)
    assert m.with_range(0.0, 1.0).extend == e
    d = sj.model_to_dict(_model())
    d.pop("extend")
    old = sj.model_from_dict(d)
    assert old.extend == 0.0 and np.array_equal(np.asarray(old.levels), np.asarray(_model().levels))
    with pytest.raises(ValueError, match="extend"):
        GaussianPreisach.from_range(0.0, 1.0, extend=-0.1)


def test_cascade_linearisation_stores_one_relay_state_per_sample():
    """The LM linearises the whole cascade (`jax.linearize` in optimistix): without a checkpointed relay step it kept
    every switching intermediate of every relay per sample (72 bytes per sample and relay; a 60-min 100 Hz record
    needed > 22 GB in the full-rate polish).  The compiled program's temporary memory is a property of the program,
    not of the machine."""
    n = 2000
    h = GaussianPreisach.from_range(0.0, 1.0).with_linear_weights(jnp.array([1.0, 0.1, 0.0]))
    m = sj.Cascade(thermal=sj.JouleThermal(k1=jnp.asarray(0.2), k2=jnp.asarray(0.05)), hysteresis=h)
    u = jnp.asarray(2.0 + 1.5 * np.sin(np.linspace(0.0, 60.0, n)))

    def f(p):
        mm = eqx.tree_at(lambda q: (q.thermal.k1, q.hysteresis.centre), m, (p[0], p[1]))
        return mm.simulate(u, 0.1)

    def jac(p):
        _, lin = jax.linearize(f, p)
        return jax.vmap(lin)(jnp.eye(2))

    ma = jax.jit(jac).lower(jnp.array([0.2, 0.5])).compile().memory_analysis()
    if ma is None:
        pytest.skip("this backend reports no memory analysis")
    per = ma.temp_size_in_bytes / n / h.n_relays
    assert per < 24.0, f"{per:.1f} bytes per sample and relay"
