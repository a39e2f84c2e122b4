"""Discrete Preisach model (issue 6, nonlocal_memory): relay scan, memory properties, JSON, weight recovery."""

import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.models import Preisach, cv_fit_preisach, fit_preisach, relay_loop, tikhonov_matrix


def _random_model(rng, n=7, linear=False, init="descended", ramp=True):
    m = Preisach.from_range(0.0, 3.5, n_levels=n, linear=linear, init=init, ramp=ramp)
    theta = np.concatenate([rng.uniform(0.0, 1.0, m.n_relays), [0.7] if linear else [], [0.3]])
    return m.with_linear_weights(jnp.asarray(theta))


def _forc_input(alphas, u_max=3.5, step=0.1):
    """Major loop then first-order reversal curves: 0 -> alpha -> 0 per branch (segments)."""
    segs = []
    for a in [u_max] + list(alphas):
        up = np.arange(0.0, a + 1e-9, step)
        segs.append(np.concatenate([up, up[::-1]]))
    return segs


@pytest.mark.parametrize("ramp", [True, False])
@pytest.mark.parametrize("init", ["descended", "zero"])
def test_scan_matches_numpy_loop(rng, init, ramp):
    m = _random_model(rng, linear=True, init=init, ramp=ramp)
    u = np.concatenate([[1.7], rng.uniform(-0.2, 3.7, 300)])  # starts mid-range: the two inits differ
    a, b = (np.asarray(x) for x in m.thresholds())
    R = relay_loop(u, a, b, init_up=(init == "descended"), width=float(m.width))
    assert (float(m.width) > 0) == ramp
    if ramp:  # the input visits the inside of the ramps, so fractional states are exercised
        assert np.any((R > 0.01) & (R < 0.99))
    np.testing.assert_allclose(np.asarray(m.relays(u)), R, atol=1e-12)
    s = (u - float(m.u_ref)) / float(m.u_span)
    ref = R @ np.asarray(m.w) + float(m.gain) * s + float(m.offset)
    np.testing.assert_allclose(np.asarray(m.simulate(u)), ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.asarray(m.features(u) @ m.linear_weights()), ref, rtol=0, atol=1e-12)
    assert np.all(np.asarray(a) >= np.asarray(b))


def test_inits_differ_only_above_the_bottom(rng):
    d, z = _random_model(rng, init="descended"), _random_model(rng, init="zero")
    z = z.with_linear_weights(d.linear_weights())
    assert abs(float(d.simulate(jnp.array([1.7]))[0]) - float(z.simulate(jnp.array([1.7]))[0])) > 1e-6
    np.testing.assert_allclose(
        np.asarray(d.simulate(jnp.array([0.0, 2.0, 1.0]))), np.asarray(z.simulate(jnp.array([0.0, 2.0, 1.0]))), atol=1e-12
    )


def test_return_point_and_wiping_out_memory(rng):
    m = _random_model(rng, n=12)
    # 0 -> 3 -> 1 -> 2.5 -> 1.5 -> 2.5 -> 1 -> 3.3 -> 0, on a fine path
    knots = [0.0, 3.0, 1.0, 2.5, 1.5, 2.5, 1.0, 3.3, 0.0]
    u = np.concatenate([np.linspace(knots[i], knots[i + 1], 40, endpoint=False) for i in range(len(knots) - 1)] + [[0.0]])
    R = np.asarray(m.relays(u))
    y = np.asarray(m.simulate(u))
    knot = lambda i: 40 * i
    # minor loop 2.5 -> 1.5 -> 2.5 closes: back at 2.5 the state is that of the first visit (return-point memory)
    np.testing.assert_array_equal(R[knot(3)], R[knot(5)])
    # ... and coming back down to 1.0 the earlier minimum's state is restored (the 1.5 reversal is wiped out)
    np.testing.assert_array_equal(R[knot(2)], R[knot(6)])
    assert not np.array_equal(R[knot(3)], R[knot(4)])
    # the loop is hysteretic (descending != ascending at 2.0), so the checks above can fail
    up, down = (
        [k for k in np.flatnonzero(np.isclose(u, 2.0)) if u[k - 1] < 2.0],
        [k for k in np.flatnonzero(np.isclose(u, 2.0)) if u[k - 1] > 2.0],
    )
    assert abs(y[up[0]] - y[down[0]]) > 1e-3
    # exceeding the previous maximum (3.3 > 3.0) wipes out all history: same state as a virgin model raised to 3.3
    k = knot(7)
    virgin = Preisach(
        w=m.w, offset=m.offset, gain=m.gain, levels=m.levels, u_ref=m.u_ref, u_span=m.u_span, width=m.width, init="zero"
    )
    fresh = np.asarray(virgin.relays(np.array([0.0, 3.3])))[-1]
    np.testing.assert_array_equal(R[k], fresh)


def test_ramp_relays_equal_crisp_on_cell_edges_and_are_continuous(rng):
    ramp = _random_model(rng, n=10)
    crisp = Preisach(**{f: getattr(ramp, f) for f in ("w", "offset", "gain", "levels", "u_ref", "u_span")}, width=0.0)
    h = float(ramp.width)
    np.testing.assert_allclose(h, 3.5 / 10)
    # a path of random reversals on the cell edges (u = k h): ramp and crisp relays agree exactly
    edges = h * rng.integers(0, 11, 60).astype(float)
    u = np.concatenate(
        [np.linspace(edges[i], edges[i + 1], 1 + int(round(abs(edges[i + 1] - edges[i]) / h))) for i in range(len(edges) - 1)]
    )
    np.testing.assert_allclose(np.asarray(ramp.simulate(u)), np.asarray(crisp.simulate(u)), atol=1e-12)
    # between the edges the crisp grid jumps by whole relay weights; the ramp grid moves by at most slope x step
    fine = np.concatenate([np.linspace(0.0, 3.5, 3501), np.linspace(3.5, 0.9, 2601), np.linspace(0.9, 2.7, 1801)])
    yr, yc = (np.abs(np.diff(np.asarray(m.simulate(fine)))) for m in (ramp, crisp))
    max_relay = float(np.max(ramp.w))
    assert yc.max() > 0.5 * max_relay  # the staircase
    assert yr.max() < 0.05 * yc.max()


@pytest.mark.slow  # suite time (10-minute budget): 24 s; ramp relays vs a numpy loop run in test_ops.py, grid recovery below
def test_ramp_relays_predict_between_training_levels(rng):
    """New reversal points and input steps off the training grid: crisp relays miss by a staircase, ramps interpolate."""
    truth = _smooth_truth(n=70)  # the 'rig': a fine smooth density
    train = _forc_input([3.1, 3.0, 2.9, 2.8, 2.7, 2.6, 2.5, 2.4, 2.3, 2.2, 2.0, 1.8, 1.5], step=0.1)
    segs = [(u, np.asarray(truth.simulate(u)) + 0.01 * rng.standard_normal(u.size)) for u in train]
    test = _forc_input([3.05, 2.75, 2.45, 2.15], step=0.05)  # reversal points and steps between the training levels
    errs = {}
    for ramp in (True, False):
        fitted, _ = fit_preisach(Preisach.from_range(0.0, 3.5, n_levels=35, ramp=ramp), segs, lam=1e-3)
        e = np.concatenate([np.asarray(fitted.simulate(u)) - np.asarray(truth.simulate(u)) for u in test])
        errs[ramp] = np.max(np.abs(e))
    assert errs[True] < 0.5 * errs[False]


def test_json_round_trip(tmp_path, rng):
    m = _random_model(rng, linear=True, init="zero")
    sj.save_model(tmp_path / "p.json", m)
    back = sj.load_model(tmp_path / "p.json")
    assert isinstance(back, Preisach) and back.init == "zero" and back.linear and float(back.width) == float(m.width) > 0
    u = rng.uniform(0, 3.5, 50)
    np.testing.assert_allclose(np.asarray(back.simulate(u)), np.asarray(m.simulate(u)), atol=1e-14)


def test_bad_inputs():
    with pytest.raises(ValueError, match="u_max > u_min"):
        Preisach.from_range(1.0, 1.0)
    with pytest.raises(ValueError, match="init"):
        Preisach.from_range(0.0, 1.0, init="virgin")
    m = Preisach.from_range(0.0, 1.0, n_levels=4)
    with pytest.raises(ValueError, match="expected 11 linear weights"):
        m.with_linear_weights(jnp.zeros(3))
    with pytest.raises(ValueError, match="width must be >= 0"):
        Preisach(w=m.w, offset=m.offset, gain=m.gain, levels=m.levels, u_ref=m.u_ref, u_span=m.u_span, width=-0.1)
    with pytest.raises(ValueError, match="n\\(n\\+1\\)/2"):
        Preisach(w=jnp.zeros(5), offset=m.offset, gain=m.gain, levels=m.levels, u_ref=m.u_ref, u_span=m.u_span)


def test_tikhonov_matrix_neighbours():
    D = tikhonov_matrix(4)
    assert D.shape[1] == 10
    np.testing.assert_allclose(D.sum(axis=1), 0.0)
    np.testing.assert_allclose(D @ np.ones(10), 0.0)  # constants are not penalised
    assert D.shape[0] == 12  # 6 vertical + 6 horizontal neighbour pairs in a 4-level triangle


def _smooth_truth(n=12, linear=False):
    """A known Preisach model with a smooth, peaked weight density (SMA-like: switching up near 2.6 V, down near 1.9 V)."""
    m = Preisach.from_range(0.0, 3.5, n_levels=n, linear=linear)
    a, b = (np.asarray(x) for x in m.thresholds())
    w = np.exp(-0.5 * (((a - 2.6) / 0.4) ** 2 + ((b - 1.9) / 0.5) ** 2)) + 0.05
    return m.with_linear_weights(jnp.asarray(np.concatenate([w, [0.5] if linear else [], [0.2]])))


@pytest.mark.slow  # suite time (10-minute budget): 13 s; grid recovery runs in the Everett and inner-CV tests
def test_recovery_from_synthetic_forcs(rng):
    truth = _smooth_truth()
    sd = 0.01
    inputs = _forc_input([3.1, 3.0, 2.9, 2.8, 2.7, 2.6, 2.5, 2.4, 2.3, 2.2, 2.0, 1.6, 1.2])
    segs = [(u, np.asarray(truth.simulate(u)) + sd * rng.standard_normal(u.size)) for u in inputs]
    fitted, info = fit_preisach(Preisach.from_range(0.0, 3.5, n_levels=12), segs, lam=1e-6)
    train_rmse = np.sqrt(info["sse"] / info["n"])
    # residual at the noise level (dof-corrected), and the fitted output equals the truth to below the noise
    assert 0.7 * sd < train_rmse * np.sqrt(info["n"] / (info["n"] - info["dof"])) < 1.3 * sd
    for u in _forc_input([2.85, 2.45, 1.9]):  # reversal points not in the training set
        err = np.asarray(fitted.simulate(u)) - np.asarray(truth.simulate(u))
        assert np.sqrt(np.mean(err**2)) < sd
    assert np.all(np.asarray(fitted.w) >= 0.0)


@pytest.mark.slow  # suite time (11 s): the Preisach fit and its grid rule are tested in the default suite
def test_inner_cv_picks_the_true_grid(rng):
    truth = _smooth_truth(n=12)
    inputs = _forc_input([3.1, 2.9, 2.7, 2.5, 2.3, 2.1, 1.7])
    segs = [(u, np.asarray(truth.simulate(u)) + 0.01 * rng.standard_normal(u.size)) for u in inputs]
    model, info = cv_fit_preisach(segs, 0.0, 3.5, n_levels_grid=(5, 12), lam_grid=(1e-6, 1e-2))
    assert info["chosen"]["n_levels"] == 12 and model.n_levels == 12
    assert info["n_inner_folds"] == len(segs) - 1 and 0 < info["dof"] <= model.n_relays + 1


@pytest.mark.slow  # suite time (10-minute budget): 22 s (one compilation per FORC length); Everett is a reference method on no default path, its input checks stay below
def test_everett_reproduces_measured_forcs_and_recovers_the_grid():
    """FORCs with a reversal at every cell edge determine a Preisach grid exactly (Mayergoyz): Everett weights = the truth."""
    from smafl_jax.models import everett_weights, fit_everett

    truth = _smooth_truth(n=12)
    h = 3.5 / 12
    alphas = [h * k for k in range(1, 12)]
    segs = [(u, np.asarray(truth.simulate(u))) for u in _forc_input(alphas, step=h)]
    for interp in ("spline", "pchip", "linear"):
        w, off = everett_weights(segs, np.asarray(truth.levels), interp)
        np.testing.assert_allclose(w, np.asarray(truth.w), atol=1e-9)
        np.testing.assert_allclose(off, float(truth.offset), atol=1e-12)
    # with fewer branches the measured ones are still reproduced, and held-out FORCs are interpolated
    train = [(u, np.asarray(truth.simulate(u))) for u in _forc_input([3.1, 2.9, 2.7, 2.5, 2.3, 2.1, 1.7, 1.3], step=0.1)]
    fitted, info = fit_everett(Preisach.from_range(0.0, 3.5, n_levels=35), train)
    assert np.sqrt(info["sse"] / info["n"]) < 1e-9
    test = _forc_input([3.0, 2.6, 2.2], step=0.1)
    err = np.concatenate([np.asarray(fitted.simulate(u)) - np.asarray(truth.simulate(u)) for u in test])
    span = np.ptp(np.concatenate([np.asarray(truth.simulate(u)) for u in test]))
    assert np.max(np.abs(err)) < 0.05 * span


def test_everett_rejects_non_forc_segments():
    from smafl_jax.models import everett_weights, forc_shaped

    u = np.concatenate([np.linspace(0, 3, 20), np.linspace(3, 1, 10), np.linspace(1, 2, 5)])  # a minor loop, not a FORC
    segs = [(u, u), (np.linspace(0, 3.5, 10), np.linspace(0, 1, 10))]
    assert not forc_shaped(segs)
    assert forc_shaped([(u, u) for u in _forc_input([3.0, 2.0])])
    mid = np.r_[1.5, 2.5, 1.0]  # starts mid-range: its relays are not all down
    assert not forc_shaped([(u, u) for u in _forc_input([3.0])] + [(mid, mid)])
    with pytest.raises(ValueError, match="first-order reversal curves"):
        everett_weights(segs, np.linspace(0.1, 3.4, 12))
    with pytest.raises(ValueError, match="interp"):
        everett_weights([(np.r_[0.0, 1.0, 0.0], np.r_[0.0, 1.0, 0.0])] * 2, np.linspace(0.1, 0.9, 5), "cubic")


@pytest.mark.slow  # suite time (10-minute budget): 15 s; the inner CV runs in test_inner_cv_picks_the_true_grid, Everett below
def test_inner_cv_criteria_and_everett_candidates(rng):
    truth = _smooth_truth(n=12)
    inputs = _forc_input([3.1, 2.9, 2.7, 2.5, 2.3, 2.1, 1.7])
    segs = [(u, np.asarray(truth.simulate(u)) + 0.01 * rng.standard_normal(u.size)) for u in inputs]
    for crit, key in (("rmse", "cv_rmse"), ("max", "cv_max_abs")):
        model, info = cv_fit_preisach(segs, 0.0, 3.5, n_levels_grid=(12, 35), lam_grid=(1e-6, 1e-2), criterion=crit)
        assert {r["method"] for r in info["cv_table"]} == {"penalised", "everett-spline", "everett-pchip", "everett-linear"}
        assert info["chosen"][key] == min(r[key] for r in info["cv_table"]) and info["criterion"] == crit
        assert info["method"] == info["chosen"]["method"] and model.n_levels == info["chosen"]["n_levels"]
    with pytest.raises(ValueError, match="criterion"):
        cv_fit_preisach(segs, 0.0, 3.5, criterion="bic")
    # segments that are not FORCs: no Everett candidate
    minor = [np.concatenate([u, np.linspace(0.0, 1.5, 16)]) for u in inputs[:3]]
    _, info = cv_fit_preisach(
        [(u, np.asarray(truth.simulate(u))) for u in minor], 0.0, 3.5, n_levels_grid=(12,), lam_grid=(1e-3,)
    )
    assert {r["method"] for r in info["cv_table"]} == {"penalised"}


def test_penalised_solver_matches_bounded_least_squares(rng):
    """NNLS with split free columns = scipy's BVLS on the same penalised problem (KKT: same unique minimiser)."""
    from scipy.optimize import lsq_linear

    from smafl_jax.models import solve_penalised

    A = rng.standard_normal((80, 12))
    y = A @ np.r_[rng.uniform(-1, 1, 9), -2.0, 0.5, 3.0] + 0.1 * rng.standard_normal(80)
    nonneg = np.r_[np.ones(10, bool), np.zeros(2, bool)]
    P = 0.3 * np.eye(12)
    x, dof = solve_penalised(A, y, nonneg, P, 1.0)
    aug_A, aug_y = np.vstack([A, np.sqrt(0.3) * np.eye(12)]), np.r_[y, np.zeros(12)]
    ref = lsq_linear(aug_A, aug_y, bounds=(np.where(nonneg, 0.0, -np.inf), np.inf), method="bvls", tol=1e-14).x
    np.testing.assert_allclose(x, ref, atol=1e-8)
    assert np.any(x[:10] == 0.0) and x[10] < 0  # some bounds active, free columns signed
    assert 0 < dof < 12
