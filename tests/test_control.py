"""Closed-loop control: scan vs numpy loop, open-loop plant, saturation/anti-windup, sweeps, sharding, CLI."""

import dataclasses
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.control import (
    PID,
    ClosedLoop,
    IICompensator,
    batch_configs,
    closed_loop_metrics,
    plant_init,
    plant_step,
    simulate_closed_loop,
    sine_reference,
    stack_models,
    step_reference,
    sweep,
)

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def truth():
    return sj.load_model(ROOT / "datasets" / "truth.json")


def _perturbed(model, seed=3, rel=0.1, k1=sj.PAPER_K1):
    """A different (mismatched) model: thermal constant changed, gains scaled by random factors."""
    rng = np.random.default_rng(seed)
    h = model.hysteresis
    th = np.asarray(h.linear_weights())
    h = h.with_linear_weights(th * (1 + rel * rng.uniform(-1, 1, th.shape)))
    return sj.Cascade(thermal=sj.JouleThermal(k1=k1, k2=model.thermal.k2), hysteresis=h)


# -- numpy reference of the whole closed loop (written independently of the JAX code) --


class _NPPlant:
    def __init__(self, model, u_init, dt):
        if isinstance(model, sj.Cascade):
            self.k1, self.k2 = float(model.thermal.k1), float(model.thermal.k2)
            self.a = np.exp(-self.k1 * dt)
            self.g = self.k2 / self.k1
            self.theta = self.g * u_init**2 if model.thermal.init == "steady" else 0.0
            h = model.hysteresis
        else:
            self.k1 = None
            h = model
        self.h = h
        n_alpha, n_ra = np.shape(h.w)
        self.r = np.concatenate([np.asarray(h.r_sym), np.tile(np.asarray(h.r_asym), n_alpha)])
        self.al = np.concatenate([np.ones(len(h.r_sym)), np.repeat(np.asarray(h.alpha), n_ra)])
        self.theta_w = np.asarray(h.linear_weights())
        self.ops = None

    def step(self, u):
        if self.k1 is not None:
            self.theta = self.a * self.theta + (1 - self.a) * self.g * u * u
            ueff = np.sqrt(max(self.theta, 0.0) * self.k1 / self.k2)
        else:
            ueff = u
        s = (ueff - float(self.h.u_ref)) / float(self.h.u_span)
        if self.ops is None:
            assert self.h.init == "descended"
            self.ops = self.al * (s + self.r)
        self.ops = np.maximum(s - self.r, np.minimum(self.al * (s + self.r), self.ops))
        powers = [s ** (m + 2) for m in range(len(self.h.poly))]
        row = np.concatenate([[s], self.ops, powers, [1.0]])
        return float(row @ self.theta_w)


def _np_closed_loop(plant, comp_model, K, kp, ki, kd, tf, umin, umax, ref, dt, noise, quantum, anti_windup=True, h_only=True):
    P = _NPPlant(plant, 0.0, dt)
    y = P.step(0.0)
    if comp_model is not None:
        H = _NPPlant(comp_model.hysteresis if (h_only and isinstance(comp_model, sj.Cascade)) else comp_model, 0.0, dt)
        yhat = H.step(0.0)
    u2 = 0.0
    integ = deriv = 0.0
    ym_prev = y
    ys, us, integs = [], [], []
    for k, r in enumerate(ref):
        ym = y + noise[k]
        if quantum > 0:
            ym = np.round(ym / quantum) * quantum
        e = r - ym
        if comp_model is not None:
            u2 = min(max(u2 + dt * K * (r - yhat), umin), umax)
            yhat = H.step(u2)
        p = kp * e
        deriv = (tf * deriv - kd * (ym - ym_prev)) / (tf + dt)
        it = integ + ki * dt * e
        raw = p + it + deriv + u2
        if anti_windup and ((raw > umax and e > 0) or (raw < umin and e < 0)):
            it = integ
        integ = it
        u = min(max(p + integ + deriv + u2, umin), umax)
        ys.append(y)
        us.append(u)
        integs.append(integ)
        y = P.step(u)
        ym_prev = ym
    return np.array(ys), np.array(us), np.array(integs)


def test_plant_step_matches_open_loop_simulate(truth, rng):
    """The per-sample plant used in the loop equals sj.simulate(model, u, dt) on an open-loop record."""
    u = np.clip(np.cumsum(rng.normal(0, 0.4, 400)) + 3.0, 0, 7.4)
    for model, dt in [(truth, 0.1), (_perturbed(truth), 0.5), (truth.hysteresis, 1.0)]:

        def f(st, uk):
            return plant_step(model, st, uk, jnp.asarray(dt))

        _, y = jax.lax.scan(f, plant_init(model, u[0]), jnp.asarray(u))
        np.testing.assert_allclose(np.asarray(y), np.asarray(sj.simulate(model, u, dt)), rtol=0, atol=1e-12)
    # ambient thermal start, different EUPI init rules
    for init in ("zero", "consistent"):
        m = sj.Cascade(
            thermal=sj.JouleThermal(k1=0.07, k2=0.05, init="ambient"), hysteresis=dataclasses.replace(truth.hysteresis, init=init)
        )
        _, y = jax.lax.scan(lambda st, uk: plant_step(m, st, uk, jnp.asarray(0.2)), plant_init(m, 0.0), jnp.asarray(u))
        np.testing.assert_allclose(np.asarray(y), np.asarray(sj.simulate(m, u, 0.2)), rtol=0, atol=1e-12)


@pytest.mark.parametrize("composite", [False, True])
def test_scan_matches_numpy_loop(truth, composite):
    dt = 0.05
    ref = sine_reference(30, dt)
    noise = 0.01 * np.asarray(jax.random.normal(jax.random.PRNGKey(7), (len(ref),), dtype=jnp.float64))
    comp_model = _perturbed(truth) if composite else None
    kw = dict(kp=20.0, ki=8.0, kd=0.7, tf=0.2, umin=0.0, umax=7.4)
    loop = ClosedLoop(
        plant=truth,
        pid=PID(**kw),
        reference=jnp.asarray(ref),
        compensator=IICompensator(comp_model, 3.0) if composite else None,
        noise_sd=0.01,
        quantum=1e-3,
        key=jax.random.PRNGKey(7),
    )
    m, out = simulate_closed_loop(loop, dt)
    y, u, integ = _np_closed_loop(truth, comp_model, 3.0, *kw.values(), ref, dt, noise, 1e-3)
    np.testing.assert_allclose(np.asarray(out["y"]), y, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.asarray(out["u"]), u, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.asarray(out["integral"]), integ, rtol=0, atol=1e-9)
    assert np.isclose(float(m["e_mean_mm"]), np.mean(np.abs(ref - y)), rtol=1e-10)
    assert np.isclose(float(m["e_mean_mm"]), float(sj.e_mean(ref, y)), rtol=1e-10)
    mm = closed_loop_metrics(loop, dt)
    for k in m:
        assert np.isclose(float(mm[k]), float(m[k]), rtol=1e-12)


def test_saturation_and_anti_windup(truth):
    """An unreachable reference saturates the drive; clamping keeps the integrator bounded, without it it runs away."""
    dt = 0.05
    ref = jnp.full(1200, 9.0)  # 9 mm is above what 7.4 V can give
    res = {}
    for aw in (True, False):
        loop = ClosedLoop(plant=truth, pid=PID(35.0, 20.0, 0.0, anti_windup=aw), reference=ref)
        m, out = simulate_closed_loop(loop, dt)
        u = np.asarray(out["u"])
        assert u.min() >= 0.0 and u.max() <= 7.4
        res[aw] = (m, np.asarray(out["integral"]), u)
    m, integ, u = res[True]
    assert float(m["saturated_fraction"]) > 0.95
    assert np.all(u[5:] == 7.4)
    assert np.max(np.abs(integ)) < 7.4 + 35 * 9.0  # frozen while saturated, no run-away
    assert np.ptp(integ[len(integ) // 2 :]) == 0.0
    _, integ_nw, _ = res[False]
    assert integ_nw[-1] > 20 * np.max(np.abs(integ))  # the windup the clamp prevents
    # after the reference comes back into range, the anti-windup loop recovers much faster
    ref2 = jnp.concatenate([jnp.full(600, 9.0), jnp.full(1400, 2.0)])
    errs = {}
    for aw in (True, False):
        loop = ClosedLoop(plant=truth, pid=PID(35.0, 20.0, 0.0, anti_windup=aw), reference=ref2)
        _, out = simulate_closed_loop(loop, dt)
        errs[aw] = np.mean(np.abs(np.asarray(out["error"])[600:]))
    assert errs[True] < 0.5 * errs[False]


def test_composite_compensator_converges_to_model_inverse(truth):
    """With the plant's own hysteresis as H and a slow reference, u2 is the quasi-static inverse."""
    dt = 0.05
    ref = step_reference(200, dt, height=2.5)
    loop = ClosedLoop(plant=truth, pid=PID(0.0, 0.0, 0.0), reference=jnp.asarray(ref), compensator=IICompensator(truth, 10.0))
    m, out = simulate_closed_loop(loop, dt)
    # pure feedforward: the plant settles where the model says, tracking error -> 0
    assert abs(float(out["y"][-1]) - 2.5) < 1e-4  # thermal lag: exp(-200 s / 16 s) ~ 4e-6 of the step left
    assert float(m["e_mean_mm"]) < 0.5


def test_sweep_matches_single_runs_and_shapes(truth):
    dt = 0.05
    base = ClosedLoop(
        plant=truth, pid=PID(), reference=jnp.asarray(sine_reference(20, dt)), compensator=IICompensator(_perturbed(truth), 10.0)
    )
    kps, Ks = np.array([10.0, 35.0]), np.array([0.0, 4.0, 10.0])
    res = sweep(base, dt, {"pid.kp": kps, "compensator.K": Ks})
    assert res.shape == (2, 3) and res.metrics["e_mean_mm"].shape == (2, 3)
    for i, kp in enumerate(kps):
        for j, K in enumerate(Ks):
            one = eqx.tree_at(lambda c: (c.pid.kp, c.compensator.K), base, (jnp.asarray(kp), jnp.asarray(K)))
            m = closed_loop_metrics(one, dt)
            for name in m:
                assert np.isclose(res.metrics[name][i, j], float(m[name]), rtol=1e-10, atol=1e-14)
    # posterior-like batch of plant models + references, zipped
    models = stack_models([_perturbed(truth, seed=s, rel=0.05) for s in range(3)])
    refs = np.stack([sine_reference(20, dt), step_reference(20, dt), step_reference(20, dt, height=1.0)])
    res2 = sweep(base, dt, {"plant": models, "reference": refs}, mode="zip")
    assert res2.shape == (3,)
    one = eqx.tree_at(lambda c: (c.plant, c.reference), base, (_perturbed(truth, seed=1, rel=0.05), jnp.asarray(refs[1])))
    assert np.isclose(res2.metrics["e_mean_mm"][1], float(closed_loop_metrics(one, dt)["e_mean_mm"]), rtol=1e-10)


def test_sweeps_of_nearby_sizes_share_one_program(truth):
    """A sweep smaller than one chunk runs at its size rounded up (`_rounded_up`): a 10x10 grid after a 12x9 one (both
    112 configurations) compiles no new closed-loop program; each new size compiled its own before (1.4 s, session 37)."""
    from smafl_jax.control import _sweep  # private: the jitted chunk runner whose compiled programs are counted

    base = ClosedLoop(plant=truth, pid=PID(kp=20.0, ki=8.0), reference=jnp.asarray(sine_reference(2, 0.05)))
    first = sweep(base, 0.05, {"pid.kp": np.linspace(5, 30, 12), "pid.ki": np.linspace(1, 9, 9)})
    programs = _sweep._run_partitioned._cached._cache_size()
    second = sweep(base, 0.05, {"pid.kp": np.linspace(5, 30, 10), "pid.ki": np.linspace(1, 9, 10)})
    assert first.shape == (12, 9) and second.shape == (10, 10)
    assert _sweep._run_partitioned._cached._cache_size() == programs
    one = eqx.tree_at(lambda c: (c.pid.kp, c.pid.ki), base, (jnp.asarray(30.0), jnp.asarray(9.0)))
    assert np.isclose(second.metrics["rmse_mm"][-1, -1], float(closed_loop_metrics(one, 0.05)["rmse_mm"]), rtol=1e-10)


def test_sweep_bad_inputs(truth):
    base = ClosedLoop(plant=truth, pid=PID(), reference=jnp.zeros(10))
    with pytest.raises(ValueError, match="does not name a field"):
        batch_configs(base, {"pid.kq": [1.0]})
    with pytest.raises(ValueError, match="None in the base"):
        batch_configs(base, {"compensator.K": [1.0]})
    with pytest.raises(ValueError, match="shape"):
        batch_configs(base, {"pid.kp": [[1.0, 2.0]]})
    with pytest.raises(ValueError, match="zip"):
        batch_configs(base, {"pid.kp": [1.0, 2.0], "pid.ki": [1.0]}, mode="zip")
    with pytest.raises(ValueError, match="umax > umin"):
        PID(umin=1.0, umax=0.5)
    with pytest.raises(TypeError, match="Cascade"):
        ClosedLoop(plant=sj.JouleThermal(), pid=PID(), reference=jnp.zeros(10))
    with pytest.raises(ValueError, match="sample time must be a finite number of seconds > 0"):
        closed_loop_metrics(base, 0.0)


def test_closed_loop_runs_inside_a_users_jit_and_grad(truth):
    """`closed_loop_metrics` / `simulate_closed_loop` inside a user's `jax.jit` and `jax.grad` (a Python check of dt
    raised a ConcretizationTypeError there, session 37 trial 3); the compiled check still refuses dt <= 0."""
    pid = PID(kp=20.0, ki=8.0, kd=0.7, tf=0.2, umin=0.0, umax=7.4)
    base = ClosedLoop(plant=truth, pid=pid, reference=jnp.asarray(sine_reference(10, 0.01)))
    direct = float(closed_loop_metrics(base, 0.01)["rmse_mm"])
    jitted = jax.jit(lambda loop, dt: closed_loop_metrics(loop, dt)["rmse_mm"])
    assert float(jitted(base, 0.01)) == pytest.approx(direct, rel=1e-12)
    traj = jax.jit(lambda loop, dt: simulate_closed_loop(loop, dt)[0]["rmse_mm"])
    assert float(traj(base, 0.01)) == pytest.approx(direct, rel=1e-12)

    def rmse(kp):
        return closed_loop_metrics(eqx.tree_at(lambda m: m.pid.kp, base, kp), 0.01)["rmse_mm"]

    kp = jnp.asarray(float(base.pid.kp))
    g = float(jax.jit(jax.grad(rmse))(kp))
    h = 1e-4 * float(kp)
    fd = (float(rmse(kp + h)) - float(rmse(kp - h))) / (2 * h)
    assert g == pytest.approx(fd, rel=1e-4, abs=1e-12)
    checked = eqx.filter_jit(lambda loop, dt: closed_loop_metrics(loop, dt)["rmse_mm"])
    with pytest.raises(eqx.EquinoxRuntimeError, match="dt must be > 0"):
        checked(base, jnp.asarray(-0.01))  # an array: traced (filter_jit keeps a Python float static, checked in Python)


_SHARD_SCRIPT = textwrap.dedent(
    """
    import json, sys
    import jax, jax.numpy as jnp, numpy as np
    import smafl_jax as sj
    from smafl_jax.control import PID, ClosedLoop, IICompensator, step_reference, sweep
    assert len(jax.devices()) == 4, jax.devices()
    truth = sj.load_model(sys.argv[1])
    dt = 0.05
    base = ClosedLoop(plant=truth, pid=PID(), reference=jnp.asarray(step_reference(10, dt)), compensator=IICompensator(truth, 10.0))
    grid = {"pid.kp": np.linspace(5, 50, 7), "compensator.K": np.array([0.0, 10.0])}  # 14 configs: padded to 16
    a = sweep(base, dt, grid, shard=True).metrics
    b = sweep(base, dt, grid, shard=False).metrics
    print(json.dumps({k: float(np.max(np.abs(a[k] - b[k]))) for k in a}))
    """
)


def test_sharded_sweep_equals_unsharded_on_4_host_devices(tmp_path):
    script = tmp_path / "shard.py"
    script.write_text(_SHARD_SCRIPT)
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=4", JAX_PLATFORMS="cpu")
    proc = subprocess.run(
        [sys.executable, str(script), str(ROOT / "datasets" / "truth.json")], env=env, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    diffs = json.loads(proc.stdout.strip().splitlines()[-1])
    assert all(v <= 1e-12 for v in diffs.values()), diffs
