"""Parallel-in-time evaluation wired into the models (issue 15): every method against scan and numpy loops.

EUPI (both orientations, every init rule), JouleThermal (every init rule) and Cascade are run with
``method`` in scan / assoc / chunked / segmented / auto; the records are long enough (1100 samples)
that chunked runs several blocks and segmented many uneven pieces, both with padding.
"""

import dataclasses
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from reference import play_loop, random_reversals, thermal_loop

import smafl_jax as sj
from smafl_jax.models import MODEL_METHODS, choose_model_method, model_with_method

PARALLEL = ("assoc", "chunked", "segmented")
ALL = ("auto", "scan", *PARALLEL)
T = 1100  # > one 1024-sample block (chunked pads a second one); 68 segments of 17 samples, padded
DT = 0.05


# ---------------------------------------------------------------- numpy references
def eupi_reference(m, u):
    """EUPI output term by term on numpy arrays, with the init rule and orientation written out."""
    s = (np.asarray(u, float) - float(m.u_ref)) / float(m.u_span)
    r_sym, r_asym, alpha, w = (np.asarray(x, float) for x in (m.r_sym, m.r_asym, m.alpha, m.w))

    def y0(r, a):
        if m.init == "descended":
            return a * (s[0] + r)
        if m.init == "consistent":
            return np.maximum(s[0] - r, np.minimum(a * (s[0] + r), 0.0))
        return np.zeros_like(r)

    ops = float(m.gain) * s + play_loop(s, r_sym, 1.0, y0(r_sym, 1.0)) @ np.asarray(m.v, float)
    for i, a in enumerate(alpha):
        ops = ops + play_loop(s, r_asym, a, y0(r_asym, a)) @ w[i]
    # s^n on the model's range [0, 1], continued with its end value and slope outside it
    poly = sum(
        c * np.where(s > 1.0, 1.0 + (j + 2) * (s - 1.0), np.where(s < 0.0, 0.0, np.clip(s, 0.0, 1.0) ** (j + 2)))
        for j, c in enumerate(np.asarray(m.poly, float))
    )
    return m.orientation * ops + poly + float(m.offset)


def thermal_reference(th, u, dt):
    k1, k2 = float(th.k1), float(th.k2)
    g = k2 / k1
    theta0 = {"steady": g * u[0] ** 2, "ambient": 0.0}.get(th.init)
    if th.init == "given":
        theta0 = g * float(th.u0) ** 2
    return thermal_loop(u, dt, k1, k2, theta0)


def cascade_reference(c, u, dt):
    theta = thermal_reference(c.thermal, u, dt)
    u_eff = np.sqrt(np.maximum(theta, 0.0) * float(c.thermal.k1) / float(c.thermal.k2))
    return eupi_reference(c.hysteresis, u_eff if c.sees == "voltage" else u_eff**2)


# ---------------------------------------------------------------- models
def random_eupi(rng, init="descended", orientation=1, method="scan"):
    m = sj.EUPI.from_range(
        0.0, 7.4, n_sym=5, n_alpha=3, n_asym=4, poly_order=3, init=init, orientation=orientation, method=method
    )
    theta = rng.uniform(0.05, 1.0, m.linear_weights().shape[0])
    theta[-3:] = rng.normal(size=3)  # polynomial and offset are free in sign
    return m.with_linear_weights(theta)


def random_thermal(rng, init="steady", method="scan"):
    u0 = jnp.asarray(rng.uniform(0.5, 5.0)) if init == "given" else None
    return sj.JouleThermal(k1=rng.uniform(0.05, 0.5), k2=rng.uniform(0.02, 0.1), init=init, u0=u0, method=method)


def random_cascade(rng, method="scan", thermal_init="steady", init="descended", sees="voltage"):
    return sj.Cascade(random_thermal(rng, thermal_init, method), random_eupi(rng, init, 1, method), sees=sees)


def scale(y):
    return max(1.0, float(np.max(np.abs(y))))


# ---------------------------------------------------------------- agreement
@pytest.mark.parametrize("method", ALL)
def test_every_method_matches_scan_and_numpy(rng, method):
    """EUPI (3 inits x 2 orientations), JouleThermal (3 inits) and Cascade, eager so each kernel compiles once."""
    u = random_reversals(rng, T, lo=0.3)
    for init in ("descended", "zero", "consistent"):
        for orientation in (1, -1):
            m = random_eupi(rng, init, orientation)
            ref = eupi_reference(m, u)
            scan = np.asarray(m.simulate(u))
            got = np.asarray(dataclasses.replace(m, method=method).simulate(u))
            # clamps compose with max/min only: the states are bit-identical, the weighted sums differ by summation order
            assert np.max(np.abs(got - scan)) <= 1e-13 * scale(scan), ("EUPI", init, orientation)
            assert np.max(np.abs(got - ref)) <= 1e-12 * scale(ref), ("EUPI", init, orientation)
    for init in ("steady", "ambient", "given"):
        th = random_thermal(rng, init)
        ref = thermal_reference(th, u, DT)
        scan = np.asarray(th.simulate(u, DT))
        got = np.asarray(dataclasses.replace(th, method=method).simulate(u, DT))
        # affine maps re-associate products and sums: agreement to rounding, not bit for bit
        np.testing.assert_allclose(got, scan, rtol=1e-13, atol=1e-14 * scale(scan), err_msg=init)
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-14 * scale(ref), err_msg=init)
    cases = (("steady", "descended", "voltage"), ("ambient", "zero", "heat"), ("given", "consistent", "voltage"))
    for thermal_init, init, sees in cases:
        c = random_cascade(rng, "scan", thermal_init, init, sees)
        ref = cascade_reference(c, u, DT)
        scan = np.asarray(c.simulate(u, DT))
        got = np.asarray(c.with_method(method).simulate(u, DT))
        assert np.max(np.abs(got - scan)) <= 1e-12 * scale(scan), ("Cascade", thermal_init, init, sees)
        assert np.max(np.abs(got - ref)) <= 1e-11 * scale(ref), ("Cascade", thermal_init, init, sees)


def test_with_method_switches_both_parts_and_keeps_parameters(rng):
    c = random_cascade(rng, "scan", "given", sees="heat")
    d = c.with_method("chunked")
    assert d.sees == "heat"
    assert (d.thermal.method, d.hysteresis.method) == ("chunked", "chunked")
    for a, b in zip(jax.tree.leaves(c), jax.tree.leaves(d)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert d.thermal.init == "given" and d.hysteresis.init == c.hysteresis.init
    with pytest.raises(ValueError, match="method"):
        c.with_method("fast")


def test_auto_resolves_to_a_real_method_and_matches_it(rng):
    c = random_cascade(rng)
    u = random_reversals(rng, T)
    chosen = choose_model_method(T, c.hysteresis.n_operators)
    assert chosen in MODEL_METHODS and chosen != "auto"
    np.testing.assert_array_equal(
        np.asarray(sj.simulate(c.with_method("auto"), u, DT)), np.asarray(sj.simulate(c.with_method(chosen), u, DT))
    )


def test_bad_method_is_rejected():
    with pytest.raises(ValueError, match="EUPI method"):
        sj.EUPI.from_range(0.0, 7.4, method="fast")
    with pytest.raises(ValueError, match="JouleThermal method"):
        sj.JouleThermal(method="parallel")


def test_method_survives_save_and_load(rng, tmp_path):
    c = random_cascade(rng, "assoc", "given")
    sj.save_model(tmp_path / "m.json", c)
    back, _ = sj.load_model_file(tmp_path / "m.json")
    assert (back.thermal.method, back.hysteresis.method) == ("assoc", "assoc")


# ---------------------------------------------------------------- gradients, vmap, traces
# the associative-scan gradient compiles slowly on CPU (~5-15 s per form): segmented by default, the others slow
@pytest.mark.parametrize(
    "method", ["segmented", pytest.param("assoc", marks=pytest.mark.slow), pytest.param("chunked", marks=pytest.mark.slow)]
)
def test_gradients_agree_with_scan(rng, method):
    u = random_reversals(rng, 600)
    y = np.asarray(sj.simulate(random_cascade(np.random.default_rng(7)), u, DT)) + 0.01 * rng.standard_normal(600)
    c = random_cascade(rng, "scan", "given", "consistent")

    def loss(model):
        return jnp.mean((model.simulate(u, DT) - y) ** 2)

    grad = eqx.filter_jit(eqx.filter_grad(loss))
    g_scan, g = grad(c), grad(c.with_method(method))
    # the output does not depend on k2 (its gradient is rounding noise around 0), so compare on the gradient's scale
    flat_scan, flat = (np.concatenate([np.ravel(x) for x in jax.tree.leaves(gr)]) for gr in (g_scan, g))
    np.testing.assert_allclose(flat, flat_scan, rtol=1e-9, atol=1e-10 * np.max(np.abs(flat_scan)))
    # and the parallel gradient is the derivative of the loss: central difference in k1 and in one gain
    for get in (lambda m: m.thermal.k1, lambda m: m.hysteresis.v):
        base = get(c)
        e = jnp.zeros_like(base).at[(0,) * base.ndim].set(1e-6)
        fd = (loss(eqx.tree_at(get, c, base + e)) - loss(eqx.tree_at(get, c, base - e))) / 2e-6
        an = np.ravel(np.asarray(get(g)))[0]
        assert abs(an - float(fd)) <= 1e-5 * max(1e-3, abs(float(fd)))


@pytest.mark.parametrize("method", PARALLEL)
def test_jitted_vmapped_simulate_shapes_and_one_trace(rng, method):
    """A jitted, vmapped simulate: (B, T) outputs equal to scan's, and one trace for new values of the same shapes."""

    def body(model, u, dt):
        return jax.vmap(lambda x: model.simulate(x, dt))(u)

    traced = eqx.debug.assert_max_traces(body, max_traces=1)
    run = eqx.filter_jit(traced)
    for _ in range(3):  # new parameter values, new records, new dt: same shapes, so no retrace
        c = random_cascade(rng, method, "given")
        u = np.stack([random_reversals(rng, 300) for _ in range(3)])
        dt = rng.uniform(0.01, 0.1)
        out = run(c, jnp.asarray(u), jnp.asarray(dt))
        assert out.shape == (3, 300)
        expected = np.stack([np.asarray(c.with_method("scan").simulate(x, dt)) for x in u])
        np.testing.assert_allclose(np.asarray(out), expected, rtol=1e-12, atol=1e-12)
    assert eqx.debug.get_num_traces(traced) == 1


def test_cli_simulate_method_matches_scan(tmp_path):
    from smafl_jax.cli import main as cli_main

    root = Path(__file__).resolve().parents[1] / "datasets"
    outs = {}
    for method in ("scan", "segmented"):
        out = tmp_path / f"{method}.csv"
        assert (
            cli_main(["simulate", str(root / "truth.json"), str(root / "minor_loop.csv"), "--out", str(out), "--method", method])
            == 0
        )
        outs[method] = np.loadtxt(out, delimiter=",", skiprows=1)
    np.testing.assert_allclose(outs["segmented"], outs["scan"], rtol=1e-12, atol=1e-13)


def test_model_with_method_reaches_nested_parts_and_rejects_models_without_them(rng):
    lag = sj.JouleLag()
    assert model_with_method(lag, "assoc").thermal.method == "assoc"
    c = model_with_method(random_cascade(rng), "chunked")
    assert (c.thermal.method, c.hysteresis.method) == ("chunked", "chunked")
    with pytest.raises(ValueError, match="no EUPI or JouleThermal"):
        model_with_method(sj.Preisach.from_range(0.0, 7.4), "assoc")
