"""The variable-projection engine (`smafl_jax.identify.varpro`): searches with a known minimum, profiled losses
equal to the returned model's loss, each caller against a plain reference of its procedure, one trace per shape."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import minimize, minimize_scalar

import smafl_jax as sj
from smafl_jax.effects import Linear, Log, LogBox, Tanh
from smafl_jax.identify import linear, varpro

# -- the engine on small problems with a known minimum ----------------------------------------


def _exp_problem(rates, gains, n=200, dt=0.05):
    """Noise-free sum of decaying exponentials plus an offset: linear in gains and offset, nonlinear in the rates."""
    t = np.arange(n) * dt
    y = sum(g * np.exp(-k * t) for k, g in zip(rates, gains)) + 0.3
    return t, y


def _exp_projection(t, y, n_rates):
    """``x`` = log rates; the model is ``(rates, theta)``; gains >= 0, offset free."""
    return varpro.LinearProjection(
        build=lambda x: (np.exp(x), None),
        design=lambda m: (np.column_stack([np.exp(-k * t) for k in m[0]] + [np.ones_like(t)]), y),
        nonneg=np.array([True] * n_rates + [False]),
        set_gains=lambda m, theta: (m[0], np.asarray(theta)),
        options=varpro.DIAGNOSE_SOLVE,
    )


def test_bounded_search_finds_a_known_rate():
    t, y = _exp_problem([0.7], [1.5])
    project = _exp_projection(t, y, 1)
    grid = np.geomspace(0.01, 100.0, 15)
    res = varpro.search(project, grid, x_of=lambda k: np.array([np.log(k)]), refine=varpro.Bounded(xatol=1e-9))
    assert res.refined and 0 < res.start < grid.size - 1
    assert np.exp(res.x[0]) == pytest.approx(0.7, rel=1e-6)
    rates, theta = res.profiled.model
    np.testing.assert_allclose(theta, [1.5, 0.3], rtol=1e-5)
    assert res.profiled.loss < 1e-12
    # the grid losses are the projections at the grid points
    np.testing.assert_allclose(res.start_losses, [project(np.array([np.log(k)])).loss for k in grid], rtol=1e-12)


def test_nelder_mead_search_finds_two_known_rates():
    t, y = _exp_problem([0.3, 4.0], [1.0, 0.6])
    project = _exp_projection(t, y, 2)
    starts = [np.log([a, b]) for a in (0.05, 0.5) for b in (2.0, 20.0)]
    nm = varpro.NelderMead(steps=(0.5, 0.5), xatol=1e-9, fatol=1e-20, maxiter=2000)
    res = varpro.search(project, starts, x_of=lambda x: x, refine=nm)
    np.testing.assert_allclose(np.sort(np.exp(res.x)), [0.3, 4.0], rtol=1e-4)
    assert res.profiled.loss <= res.start_losses[res.start] and res.best_seen.loss == pytest.approx(res.profiled.loss)


def test_nelder_mead_from_the_runners_up_leaves_a_wrong_basin():
    """Two basins: the best scored start lies in the shallow one (loss 0.3 at x = 0.5), the runner-up in the deep one
    (0 at x = 2.6).  One simplex stays in the shallow basin; ``n_starts=2`` refines both and keeps the deep one."""

    def project(x, start=None):
        v = float(min((x[0] - 0.5) ** 2 + 0.3, 4.0 * (x[0] - 2.6) ** 2))
        return varpro.Profiled(v, x.copy())

    starts = [0.4, 2.0, 5.0]  # start losses 0.31, 1.44, 20.55
    one = varpro.search(project, starts, x_of=lambda s: np.array([s]), refine=varpro.NelderMead(steps=(0.1,), xatol=1e-8))
    assert one.start == 0 and one.x[0] == pytest.approx(0.5, abs=1e-6) and one.profiled.loss == pytest.approx(0.3)
    nm2 = varpro.NelderMead(steps=(0.1,), xatol=1e-8, n_starts=2)
    two = varpro.search(project, starts, x_of=lambda s: np.array([s]), refine=nm2)
    assert two.start == 1 and two.x[0] == pytest.approx(2.6, abs=1e-6) and two.profiled.loss < 1e-12
    assert two.n_evals > one.n_evals and two.best_seen.loss == pytest.approx(two.profiled.loss)
    np.testing.assert_allclose(two.start_losses, [0.31, 1.44, 20.55])
    # a non-finite start is not refined: the two finite ones are (from 5.0 the simplex also reaches the deep basin)
    inf_start = varpro.search(project, starts, x_of=lambda s: np.array([s]), losses=[0.31, np.inf, 20.55], refine=nm2)
    assert inf_start.start == 2 and inf_start.x[0] == pytest.approx(2.6, abs=1e-6)
    nm3 = varpro.NelderMead(steps=(0.1,), xatol=1e-8, n_starts=3)
    only_one = varpro.search(project, starts, x_of=lambda s: np.array([s]), losses=[0.31, np.inf, np.inf], refine=nm3)
    assert only_one.start == 0 and only_one.x[0] == pytest.approx(0.5, abs=1e-6)
    with pytest.raises(ValueError, match="n_starts"):
        varpro.NelderMead(steps=(0.1,), n_starts=0)


def test_runners_up_refined_only_where_the_best_start_asks_for_it():
    """``retry_if`` sees the best start's final point: False there keeps its one simplex run, True refines the
    runners-up as ``n_starts`` alone does."""

    def project(x, start=None):
        v = float(min((x[0] - 0.5) ** 2 + 0.3, 4.0 * (x[0] - 2.6) ** 2))
        return varpro.Profiled(v, x.copy())

    starts, seen = [0.4, 2.0, 5.0], []

    def ask(answer):
        def retry_if(x):
            seen.append(float(x[0]))
            return answer

        return retry_if

    kw = dict(x_of=lambda s: np.array([s]))
    stay = varpro.search(
        project, starts, refine=varpro.NelderMead(steps=(0.1,), xatol=1e-8, n_starts=2, retry_if=ask(False)), **kw
    )
    assert stay.start == 0 and stay.n_runs == 1 and stay.x[0] == pytest.approx(0.5, abs=1e-6)
    assert seen == [pytest.approx(0.5, abs=1e-6)]  # asked once, at the best start's final point
    move = varpro.search(
        project, starts, refine=varpro.NelderMead(steps=(0.1,), xatol=1e-8, n_starts=2, retry_if=ask(True)), **kw
    )
    assert move.start == 1 and move.n_runs == 2 and move.x[0] == pytest.approx(2.6, abs=1e-6)
    assert len(seen) == 2  # not asked again after the second run
    plain = varpro.search(project, starts, refine=varpro.NelderMead(steps=(0.1,), xatol=1e-8, n_starts=2), **kw)
    assert plain.n_runs == 2 and plain.x[0] == move.x[0] and plain.n_evals == move.n_evals


@pytest.mark.parametrize(
    "transform, inside, outside",
    [
        # |v| <= 2: the outer 1 % of [-2, 2] is |v| > 1.96
        (Tanh(2.0), [0.0, 1.9, -1.95], [1.97, -1.99]),
        # log v in [log 1, log 1000]: 1 % of that range is a factor 1000 ** 0.01 = 1.072 from either end
        (LogBox(1.0, 1000.0), [1.08, 30.0, 930.0], [1.06, 940.0, 999.0]),
    ],
)
def test_at_bound_is_the_outer_percent_of_a_bounded_range(transform, inside, outside):
    for v in inside:
        assert not transform.at_bound(transform.to_phi(v)), v
    for v in outside:
        assert transform.at_bound(transform.to_phi(v)), v
    assert not Log().at_bound(40.0) and not Linear().at_bound(-1e9)  # unbounded: never


def test_grid_edge_is_not_refined_and_no_finite_start_raises():
    t, y = _exp_problem([0.7], [1.5])
    project = _exp_projection(t, y, 1)
    grid = np.geomspace(0.7, 100.0, 5)  # the truth is the first grid point
    res = varpro.search(project, grid, x_of=lambda k: np.array([np.log(k)]), refine=varpro.Bounded())
    assert res.start == 0 and not res.refined and res.n_evals == 0
    with pytest.raises(sj.UserInputError, match="nothing finite"):
        varpro.search(
            project, grid, x_of=lambda k: np.array([np.log(k)]), losses=np.full(5, np.inf), none_finite="nothing finite"
        )


def test_grid_losses_chunks_pad_to_one_shape():
    seen = []

    def evaluate(pts, n):
        seen.append(pts.shape)
        return pts[:n, 0] ** 2

    pts = np.arange(7.0)[:, None]
    np.testing.assert_array_equal(varpro.grid_losses(evaluate, pts, 3), np.arange(7.0) ** 2)
    assert seen == [(3, 1)] * 3


def test_best_start_is_the_first_minimum_and_skips_nan():
    assert varpro.best_start([3.0, np.nan, 1.0, 1.0]) == 2
    assert varpro.best_start([np.inf, 2.0]) == 1


# -- profiled losses equal the loss of the returned model -----------------------------------------


def _short_steps(datasets_dir, every=8, n=None):
    r = sj.load_record(datasets_dir / "steps.csv")
    u, y = r.u[::every], r.y[::every]
    return [(u[:n], y[:n], every * r.dt)]


def test_fit_profile_loss_is_the_returned_models_loss(datasets_dir):
    data = _short_steps(datasets_dir)
    model, info = sj.init_profile(sj.Cascade.from_range(7.4), data, k1_grid=10)
    u, y, dt = data[0]
    r = np.asarray(sj.simulate(model, u, dt)) - y
    assert info["loss"] == pytest.approx(0.5 * float(r @ r), rel=1e-8)
    assert float(model.thermal.k1) == info["k1"]


def test_diagnose_profile_loss_is_the_returned_models_sse(datasets_dir):
    from smafl_jax.diagnosis import make_split, profile_gains, simulate_segment
    from smafl_jax.effects import ExtendedModel, SensorLag

    truth = sj.load_model(datasets_dir / "truth.json")
    rec = sj.load_record(datasets_dir / "steps.csv")
    split = make_split(rec)
    m, sse = profile_gains(ExtendedModel(truth, (SensorLag(tau=jnp.asarray(2.0)),)), split.train)
    got = sum(float(np.sum((simulate_segment(m, s) - s.y)[s.mask] ** 2)) for s in split.train)
    assert sse == pytest.approx(got, rel=1e-8)


# -- each caller equals a plain reference of its procedure ---------------------------------------


def _solve_options():
    return dict(jitter=1e-13, jitter_of="trace", rhs="transpose", drop_constant=True)


def test_init_profile_equals_a_plain_grid_and_brent_search(datasets_dir):
    """The grid, its losses, the bounded Brent refinement between the neighbours and the final k1 / loss."""
    data = _short_steps(datasets_dir)
    u, y, dt = data[0]
    start = sj.Cascade.from_range(7.4)
    model, info = sj.init_profile(start, data, k1_grid=12)

    grid = np.unique(np.concatenate([np.geomspace(0.2 / (dt * u.size), 5.0 / dt, 12), [float(start.thermal.k1)]]))
    nonneg = np.asarray(start.hysteresis.nonnegative_columns())

    def loss(k1):
        A = np.asarray(eqx.tree_at(lambda m: m.thermal.k1, start, jnp.asarray(k1)).features(jnp.asarray(u), dt))
        return linear.solve(A, y, nonneg, **_solve_options()).loss

    losses = np.array([loss(k) for k in grid])
    np.testing.assert_allclose(info["k1_grid"], grid, rtol=0)
    np.testing.assert_allclose(info["profile_loss"], losses, rtol=1e-9)
    best = int(np.argmin(losses))
    assert 0 < best < grid.size - 1
    res = minimize_scalar(lambda x: loss(np.exp(x)), bounds=(np.log(grid[best - 1]), np.log(grid[best + 1])),
                          method="bounded", options={"xatol": 1e-7})  # fmt: skip
    log_k1 = float(res.x) if res.fun <= losses[best] else float(np.log(grid[best]))
    assert info["k1"] == pytest.approx(np.exp(log_k1), rel=1e-9)
    assert info["loss"] == pytest.approx(loss(np.exp(log_k1)), rel=1e-9)
    assert info["n_refine_evals"] == res.nfev


def test_refine_thermal_start_equals_a_plain_nelder_mead(datasets_dir):
    """Nelder-Mead over (log k1, u0 / u_hi), each point the one-k1 profile as `fit(solver=None)` computes it."""
    from smafl_jax.identify import refine_thermal_start

    data = _short_steps(datasets_dir, every=8, n=400)
    u_hi = float(np.max(data[0][0]))
    model = sj.Cascade.from_range(7.4).with_thermal_start("given", 0.3 * u_hi)
    weights = (np.ones(data[0][0].size),)
    loss, fitted, info = refine_thermal_start(model, data, weights, u_hi, max_evals=30)

    best = [np.inf, None]

    def objective(x):
        if not 0.0 < float(x[1]) <= 1.0:
            return np.inf
        k1 = float(np.exp(x[0]))
        m = eqx.tree_at(lambda c: c.thermal.k1, model, jnp.asarray(k1)).with_thermal_start("given", float(x[1]) * u_hi)
        res = sj.fit(m, data, weights=weights, solver=None, k1_grid=np.array([k1]))
        if res.loss < best[0]:
            best[:] = [res.loss, res.model]
        return res.loss

    x0 = np.array([np.log(float(model.thermal.k1)), 0.3])
    ref = minimize(objective, x0, method="Nelder-Mead",
                   options={"maxfev": 30, "xatol": 1e-3, "fatol": 0.0, "initial_simplex": x0 + np.array([[0, 0], [0.3, 0], [0, 0.1]])})  # fmt: skip
    assert info["refine_evals"] == ref.nfev
    assert loss == pytest.approx(best[0], rel=1e-9)
    assert float(fitted.thermal.k1) == pytest.approx(float(best[1].thermal.k1), rel=1e-9)
    assert float(fitted.thermal.u0) == pytest.approx(float(best[1].thermal.u0), rel=1e-9)
    assert loss < objective(x0)


def _at_a_bound(phi, lay):
    """Reference of the runners-up rule: a LogBox / Tanh parameter in the outer 1 % of its range (values, not phi)."""
    for (_, _, tr, _), p in zip(lay, phi):
        v = tr.from_phi(p)
        if isinstance(tr, LogBox):
            f = (np.log(v) - np.log(tr.lo)) / (np.log(tr.hi) - np.log(tr.lo))
            if min(f, 1.0 - f) < 0.01:
                return True
        elif isinstance(tr, Tanh) and abs(v) > 0.98 * tr.bound:
            return True
    return False


def test_fit_extended_equals_a_plain_grid_and_nelder_mead(datasets_dir):
    """Effect grid x k1 grid scored by `profile_gains`, Nelder-Mead with the diagnosis' simplex, caps, tolerances and
    cache from the best start (and the next `REFINED_STARTS` - 1 where it ends at a bound), the lowest final loss,
    then the gains at its point."""
    from smafl_jax.diagnosis import fit_extended, make_split, profile_gains
    from smafl_jax.diagnosis._diagnose import (  # private: white-box test of the varpro parameter layout
        REFINED_STARTS,
        _context,
        _get_phi,
        _phi_layout,
        _set_phi,
    )
    from smafl_jax.effects import ExtendedModel, SensorLag

    rec = sj.load_record(datasets_dir / "steps.csv")
    u, y = rec.u[::4][:500], rec.y[::4][:500]
    rec = sj.Record.from_arrays(np.arange(u.size) * 4 * rec.dt, u, y, input_name="voltage_V", output_name="displacement_mm")
    split = make_split(rec)
    base = sj.load_model(datasets_dir / "truth.json")
    k1s = (0.03, 0.1)
    model, info = fit_extended(base, ["sensor_lag"], split, k1_grid=k1s, max_iter=40)

    ctx = _context(split)
    starts = [
        eqx.tree_at(lambda m: m.base.thermal.k1, ExtendedModel(base, (e,)), jnp.asarray(k))
        for e in SensorLag.grid(ctx)
        for k in k1s
    ]
    scores = [profile_gains(m, split.train)[1] for m in starts]
    runs, n_evals, lay = [], 0, _phi_layout(starts[0], ctx)  # one layout: every start has the same structure
    for i in np.argsort(scores, kind="stable")[:REFINED_STARTS]:
        if runs and not _at_a_bound(runs[0][1].x, lay):
            break  # runners-up only where the best start's simplex ends at a bound
        start = starts[int(i)]
        cache = {}

        def objective(phi, start=start, cache=cache):
            key = tuple(np.round(phi, 12))
            if key not in cache:
                sse = profile_gains(_set_phi(start, lay, phi), split.train)[1]
                cache[key] = sse if np.isfinite(sse) else 1e300
            return cache[key]

        phi0 = _get_phi(start, lay)
        simplex = [phi0] + [phi0 + np.eye(len(lay))[i] * lay[i][3] for i in range(len(lay))]
        res = minimize(objective, phi0, method="Nelder-Mead",
                       options={"initial_simplex": np.array(simplex), "maxiter": 40, "xatol": 1e-4, "fatol": 1e-10})  # fmt: skip
        runs.append((res.fun, res, start))
        n_evals += len(cache)
    _, res, start = min(runs, key=lambda r: r[0])  # the first of equal losses
    ref, sse = profile_gains(_set_phi(start, lay, res.x), split.train)
    assert info["n_starts"] == len(starts) and info["n_evaluations"] == len(starts) + n_evals
    assert info["refined_runs"] == len(runs)
    assert info["converged"] == bool(res.success) and info["nonlinear_parameters"] == 2
    assert info["train_sse"] == pytest.approx(sse, rel=1e-9)
    np.testing.assert_allclose(_get_phi(model, lay), res.x, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(
        model.base.hysteresis.linear_weights(), ref.base.hysteresis.linear_weights(), rtol=1e-9, atol=1e-12
    )


# -- one trace per shape ------------------------------------------------------------------------


def _design(model, u, dt):
    return model.features(u, dt)


def _with_k1(model, k1):
    return eqx.tree_at(lambda m: m.thermal.k1, model, k1)


def test_batched_grid_design_traces_once_per_shape(datasets_dir):
    (u, _, dt), *_ = _short_steps(datasets_dir, every=16)
    before = eqx.debug.get_num_traces(varpro._batch_design_traced)
    for i, lo in enumerate((0.01, 0.02, 0.05)):  # new values (grid, model, input, dt), the same shapes
        model = sj.Cascade.from_range(7.4 + i)
        ks = jnp.asarray(np.geomspace(lo, 1.0, 4))
        A = varpro.batch_design(_design, _with_k1, model, ks, jnp.asarray(u + i), jnp.asarray(dt * (1 + i)))
        assert A.shape[0] == 4
        np.testing.assert_allclose(
            A[2], _design(_with_k1(model, ks[2]), jnp.asarray(u + i), dt * (1 + i)), rtol=1e-12, atol=1e-12
        )
    assert eqx.debug.get_num_traces(varpro._batch_design_traced) == before + 1
