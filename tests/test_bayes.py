"""Bayesian layer: log-posterior against hand-written references, Jacobian, marginalisation, vectorised
evaluation, priors from JSON, recovery, diagnostics, kill -9 resume and the `smafl sample` CLI."""

import json
import math
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

import smafl_jax as sj
from tests.reference import thermal_loop

ROOT = Path(__file__).resolve().parents[1]

# One short synthetic step record for the Joule model alone (k1, k2 both identifiable).
SETUP = textwrap.dedent(
    """
    import numpy as np, jax.numpy as jnp, smafl_jax as sj
    def make_record(seed=7, n=200, sigma=0.05):
        rng = np.random.default_rng(seed)
        dt = 0.5
        u = np.zeros(n); u[20:] = 5.0; u[n // 2:] = 2.0; u[3 * n // 4:] = 7.0
        truth = sj.JouleThermal(k1=jnp.asarray(0.0625), k2=jnp.asarray(0.055))
        y = np.asarray(truth.simulate(u, dt)) + sigma * rng.standard_normal(n)
        return u, y, dt, truth
    def make_posterior():
        u, y, dt, truth = make_record()
        return sj.Posterior(truth, (u, y), dt)
    """
)
_ns = {}
exec(SETUP, _ns)
make_record, make_posterior = _ns["make_record"], _ns["make_posterior"]


def _log_sigmoid(x):
    return -np.logaddexp(0.0, -x)


@pytest.mark.parametrize("noise", ["gaussian", "student-t"])
def test_log_posterior_matches_numpy_reference(noise):
    u, y, dt, truth = make_record()
    post = sj.Posterior(truth, (u, y), dt, noise=noise, nu=5.0, sigma=0.04)
    theta = post.theta0 + np.array([0.03, -0.02, 0.1])
    x = np.logaddexp(0.0, theta)  # softplus: physical k1, k2, sigma
    k1, k2, sig = x
    r = thermal_loop(u, dt, k1, k2, k2 / k1 * u[0] ** 2) - y
    if noise == "gaussian":
        ll = stats.norm.logpdf(r, scale=sig).sum()
    else:
        ll = stats.t.logpdf(r, df=5.0, scale=sig).sum()
    yr, umax = np.ptp(y), np.max(np.abs(u))
    lp = (
        stats.lognorm.logpdf(k1, s=2.0, scale=0.05)
        + stats.lognorm.logpdf(k2, s=3.0, scale=0.05 * yr / umax**2)
        + stats.halfnorm.logpdf(sig, scale=yr)
    )
    expected = ll + lp + _log_sigmoid(theta).sum()
    got = post(theta[None, :])[0]
    assert got == pytest.approx(expected, rel=1e-10, abs=1e-8)


def test_jacobian_prior_only_sampling_recovers_prior():
    # Sampling the prior in unconstrained coordinates must give back the physical prior;
    # without the log-Jacobian the mean of log k1 would be shifted by -scale^2 = -0.25.
    u, y, dt, truth = make_record()
    priors = {
        "k1": sj.Prior("lognormal", math.log(0.05), 0.5),
        "k2": sj.Prior("lognormal", math.log(0.05), 0.5),
        "noise.sigma": sj.Prior("halfnormal", scale=1.0),
    }
    post = sj.Posterior(truth, (u, y), dt, priors=priors, prior_only=True)
    run = sj.run_sampler(post, 2500, n_walkers=32, seed=1, progress=False)
    x = post.physical(run.chain[500:].reshape(-1, 3))
    logk1 = np.log(x[:, 0])
    assert np.mean(logk1) == pytest.approx(math.log(0.05), abs=0.08)
    assert np.std(logk1) == pytest.approx(0.5, rel=0.12)
    assert np.mean(x[:, 2]) == pytest.approx(math.sqrt(2 / math.pi), rel=0.12)  # half-normal mean


def _small_cascade_problem(n=80, seed=0):
    from tests.reference import random_reversals

    rng = np.random.default_rng(seed)
    model = sj.Cascade.from_range(7.4, n_sym=2, n_alpha=1, n_asym=2, poly_order=2)
    u = random_reversals(rng, n)
    hyst = model.hysteresis.with_linear_weights(np.array([0.3, 1.0, 0.5, 0.2, 0.1, 0.05, 0.2]))
    truth = sj.Cascade(thermal=sj.JouleThermal(k1=jnp.asarray(0.2), k2=jnp.asarray(0.05)), hysteresis=hyst)
    y = np.asarray(truth.simulate(u, 0.5)) + 0.02 * rng.standard_normal(n)
    return truth, u, y


def test_marginalised_gains_equal_dense_gaussian_marginal():
    truth, u, y = _small_cascade_problem()
    post = sj.Posterior(truth, (u, y), 0.5, linear="marginalise", gain_scale=3.0, sigma=0.03)
    assert post.names == ["thermal.k1", "noise.sigma"]
    model, sigma = post.unpack(post.theta0)
    A = np.asarray(model.hysteresis.features(model.thermal.effective_voltage(model.thermal.simulate(u, 0.5))))
    cov = float(sigma) ** 2 * np.eye(len(u)) + 3.0**2 * A @ A.T
    expected = stats.multivariate_normal(mean=np.zeros(len(u)), cov=cov).logpdf(y)
    assert float(eqx.filter_jit(post._loglik)(model, sigma)) == pytest.approx(expected, rel=1e-9)
    # profile: Gaussian log-likelihood at the ridge least-squares gains
    prof = sj.Posterior(truth, (u, y), 0.5, linear="profile", gain_scale=1e6, sigma=0.03)
    w = np.linalg.lstsq(A, y, rcond=None)[0]
    expected_p = stats.norm.logpdf(A @ w - y, scale=float(sigma)).sum()
    assert float(eqx.filter_jit(prof._loglik)(model, sigma)) == pytest.approx(expected_p, rel=1e-6)


def test_marginalise_rejects_student_t_and_models_without_gains():
    truth, u, y = _small_cascade_problem(n=30)
    with pytest.raises(sj.UserInputError, match="Gaussian"):
        sj.Posterior(truth, (u, y), 0.5, linear="marginalise", noise="student-t")
    with pytest.raises(sj.UserInputError, match="EUPI"):
        sj.Posterior(truth.thermal, (u, y), 0.5, linear="profile")
    with pytest.raises(sj.UserInputError, match="noise model"):
        sj.Posterior(truth, (u, y), 0.5, noise="cauchy")


def test_vectorised_logprob_shapes_single_trace_and_nan_to_minus_inf():
    post = make_posterior()
    rng = np.random.default_rng(0)
    thetas = post.theta0 + 0.01 * rng.standard_normal((8, post.ndim))
    lp = post(thetas)
    assert lp.shape == (8,)
    rows = [float(post.log_prob(jnp.asarray(t))) for t in thetas]
    np.testing.assert_allclose(lp, rows, rtol=1e-12)
    from smafl_jax.bayes._bayes import _log_prob_traced  # private: trace count of the jitted log-density

    n = eqx.debug.get_num_traces(_log_prob_traced)  # process-wide: counted from here
    post(thetas + 0.1)
    post(thetas - 0.1)
    assert eqx.debug.get_num_traces(_log_prob_traced) == n  # same shape: no retrace
    bad = thetas.copy()
    bad[0, 0] = np.nan
    out = post(bad)
    assert out[0] == -np.inf and np.all(np.isfinite(out[1:]))
    with pytest.raises(ValueError, match="shape"):
        post(thetas[:, :2])


def test_walker_batch_sizes():
    from smafl_jax.bayes import _bayes  # private: the batching of the jitted log-density and predictions

    assert _bayes.walker_batch(32, 30_000) == 32 and _bayes.walker_batch(32, 90_000) == 11
    assert _bayes.walker_batch(32, 360_000) == 2 and _bayes.walker_batch(4, 10**9) == 1


@pytest.mark.slow  # suite time (18 s: two compilations of the density and the predictions); the padded batching itself
# is checked against one vmap by test_in_batches_equals_one_vmap_for_every_remainder in the default suite
def test_walkers_in_batches_give_the_same_log_density_and_predictions(monkeypatch):
    """Long records evaluate the walkers in sequential batches (`walker_batch`): the memory of one batch, same values."""
    from smafl_jax.bayes import _bayes  # private: the batching of the jitted log-density and predictions

    truth, u, y = _small_cascade_problem(n=60)
    post = sj.Posterior(truth, (u, y), 0.5, linear="marginalise", gain_scale=3.0, sigma=0.03)
    rng = np.random.default_rng(1)
    thetas = jnp.asarray(post.theta0 + 0.01 * rng.standard_normal((5, post.ndim)))
    keys = jax.random.split(jax.random.PRNGKey(0), 5)
    whole = _bayes._vmapped_log_prob(post._d, thetas)
    f0, y0 = _bayes._batch_predict.__wrapped__(post._d, thetas, keys, jnp.asarray(u), jnp.asarray(0.5))
    monkeypatch.setattr(_bayes, "WALKER_SAMPLES_PER_BATCH", 2 * len(u))  # 2 walkers a batch, the last one padded
    assert _bayes.walker_batch(5, len(u)) == 2
    np.testing.assert_allclose(_bayes._vmapped_log_prob(post._d, thetas), whole, rtol=1e-9)  # batched BLAS rounding
    f1, y1 = _bayes._batch_predict.__wrapped__(post._d, thetas, keys, jnp.asarray(u), jnp.asarray(0.5))
    np.testing.assert_allclose(f1, f0, rtol=1e-9)
    np.testing.assert_allclose(y1, y0, rtol=1e-9)


def test_in_batches_equals_one_vmap_for_every_remainder():
    """Equal padded batches (no separate remainder batch: `lax.map`'s hung XLA's CPU runtime) give vmap's values."""
    from smafl_jax.bayes import _bayes  # private: the batching helper itself

    def fn(tk):
        t, k = tk
        return jnp.stack([jnp.sum(t**2), t[0] * k]), jnp.cumsum(t) * k

    xs = (jnp.asarray(np.random.default_rng(0).standard_normal((7, 3))), jnp.arange(7.0))
    whole = jax.vmap(fn)(xs)
    for batch in (1, 2, 3, 6, 7, 10):  # padded by 0, 1, 2, 5, 0 copies; the last one vmap alone
        got = jax.jit(lambda x, b=batch: _bayes._in_batches(fn, x, b))(xs)
        for a, b in zip(jax.tree_util.tree_leaves(got), jax.tree_util.tree_leaves(whole)):
            assert a.shape == b.shape
            np.testing.assert_allclose(a, b, rtol=1e-12)


def test_priors_from_json_override_and_errors(tmp_path):
    u, y, dt, truth = make_record()
    p = tmp_path / "priors.json"
    p.write_text(json.dumps({"k1": {"dist": "uniform", "low": 0.01, "high": 0.2}}))
    post = sj.Posterior(truth, (u, y), dt, priors=sj.load_priors(p))
    assert post.priors["k1"] == sj.Prior("uniform", low=0.01, high=0.2)
    theta = post.theta0.copy()
    theta[0] = math.log(math.expm1(0.5))  # k1 = 0.5, outside the uniform support
    assert post(theta[None])[0] == -np.inf
    p.write_text(json.dumps({"thermal.k9": {"dist": "normal", "loc": 0, "scale": 1}}))
    with pytest.raises(sj.UserInputError, match="unknown parameters"):
        sj.Posterior(truth, (u, y), dt, priors=sj.load_priors(p))
    p.write_text(json.dumps({"k1": {"dist": "gamma", "a": 1}}))
    with pytest.raises(sj.UserInputError, match="unknown distribution"):
        sj.load_priors(p)
    p.write_text(json.dumps({"k1": {"dist": "normal", "loc": 0}}))
    with pytest.raises(sj.UserInputError, match="needs"):
        sj.load_priors(p)
    p.write_text(json.dumps({"k1": {"dist": "halfnormal", "scale": -1}}))
    with pytest.raises(sj.UserInputError, match="scale"):
        sj.load_priors(p)


def test_recovery_summary_and_short_chain_warning():
    post = make_posterior()
    run = sj.run_sampler(post, 1500, n_walkers=24, seed=2, progress=False)
    assert run.chain.shape == (1500, 24, 3)
    s = sj.summarize(post, run, warn=False)
    for name, true in (("k1", 0.0625), ("k2", 0.055), ("noise.sigma", 0.05)):
        p = s["parameters"][name]
        assert {"mean", "sd", "q025", "q975"} <= set(p)
        assert p["q025"] < p["mean"] < p["q975"]
        # 4 sd: a criterion a correct posterior fails with probability ~1e-4 on any seed
        assert abs(p["mean"] - true) < 4 * p["sd"], (name, p)
    assert 0.2 < s["acceptance_fraction"] < 0.8
    for name, true in (("time_constant_s", 16.0), ("steady_state_gain", 0.88)):
        d = s["derived"][name]
        assert abs(d["mean"] - true) < 4 * d["sd"], (name, d)
    short = sj.run_sampler(post, 40, n_walkers=24, seed=2, progress=False)
    with pytest.warns(sj.ChainTooShortWarning, match="too short"):
        d = sj.diagnostics(short)
    assert not d["reliable"] and d["warnings"]


def test_diagnostics_of_a_chain_whose_walker_never_moved_warn_instead_of_failing():
    """A walker that never moved along a parameter has no autocorrelation estimate (emcee divides 0 by 0): the
    diagnostics count it as the whole chain and say the chain is too short (it once raised a NaN-to-int ValueError)."""
    rng = np.random.default_rng(0)
    chain = rng.standard_normal((12, 6, 2))
    chain[:, 0, 1] = 0.5  # walker 0 stuck on parameter 1
    run = sj.SampleRun(chain, np.zeros((12, 6)), np.full(6, 0.3), ["a", "b"], None, 0)
    with pytest.warns(sj.ChainTooShortWarning, match="too short"):
        d = sj.diagnostics(run)
    assert np.isfinite(d["autocorr_time"]).all() and d["autocorr_time"][1] == 12 - d["burn"] and not d["reliable"]


CHILD = SETUP + textwrap.dedent(
    """
    import sys
    post = make_posterior()
    sj.run_sampler(post, int(sys.argv[2]), n_walkers=16, path=sys.argv[1], seed=3, progress=False,
                   checkpoint_s=0.05, on_step=lambda i: print(i, flush=True))
    """
)


@pytest.mark.slow  # suite time (10-minute budget): 15 s; resuming from the checkpoint runs below, and from the CLI in the end-to-end test
def test_resume_after_sigkill_gives_exact_chain(tmp_path):
    n = 300
    post = make_posterior()
    ref = sj.run_sampler(post, n, n_walkers=16, path=tmp_path / "ref.h5", seed=3, progress=False)
    path = tmp_path / "run.h5"
    script = tmp_path / "child.py"
    script.write_text(CHILD)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, str(script), str(path), str(n)], stdout=subprocess.PIPE, text=True, env=env)
    killed_at = None
    for line in proc.stdout:
        if int(line) >= 120:
            proc.send_signal(signal.SIGKILL)
            killed_at = int(line)
            break
    proc.wait()
    assert killed_at is not None and proc.returncode == -signal.SIGKILL
    partial = sj.load_run(path, post.names)
    assert killed_at <= partial.chain.shape[0] < n  # interrupted mid-way
    run = sj.run_sampler(post, n, n_walkers=16, path=path, seed=3, progress=False)
    assert run.resumed_from == partial.chain.shape[0]
    assert run.chain.shape == (n, 16, post.ndim)
    # the resumed chain is the uninterrupted one: no lost, repeated or altered steps
    np.testing.assert_array_equal(run.chain, ref.chain)
    np.testing.assert_array_equal(run.log_prob, ref.log_prob)
    np.testing.assert_allclose(run.acceptance_fraction, ref.acceptance_fraction)
    # asking again for the same length does nothing; asking for fewer is an error
    again = sj.run_sampler(post, n, n_walkers=16, path=path, seed=3, progress=False)
    np.testing.assert_array_equal(again.chain, ref.chain)
    with pytest.raises(sj.UserInputError, match="more than"):
        sj.run_sampler(post, n - 10, n_walkers=16, path=path, seed=3, progress=False)


def test_resume_uses_checkpoint_when_live_file_is_corrupt(tmp_path):
    post = make_posterior()
    path = tmp_path / "c.h5"
    ref = sj.run_sampler(post, 80, n_walkers=16, path=tmp_path / "ref.h5", seed=4, progress=False)
    sj.run_sampler(post, 50, n_walkers=16, path=path, seed=4, progress=False)  # checkpoint at 50 steps
    path.write_bytes(path.read_bytes()[:2000])  # what a kill in the middle of a write can leave
    run = sj.run_sampler(post, 80, n_walkers=16, path=path, seed=4, progress=False)
    np.testing.assert_array_equal(run.chain, ref.chain)


def _write_fit(tmp_path):
    truth, u, y = _small_cascade_problem(n=240, seed=5)
    t = 0.5 * np.arange(len(u))
    csv = tmp_path / "rec.csv"
    sj.atomic_write_csv(csv, {"time_s": t, "voltage_V": u, "displacement_mm": y})
    rec = sj.load_record(csv)
    fitted = sj.init_linear(truth, rec)  # gains by the paper's LS at the true k1: a stand-in for `smafl fit`
    yh = np.asarray(sj.simulate(fitted, rec.u, rec.dt))
    fit_json = tmp_path / "fit.json"
    sj.save_model(
        fit_json,
        fitted,
        metrics={"train": sj.metrics(rec.y, yh)},
        data={
            "file": csv.name,
            "path": str(csv),
            "sha256": rec.sha256,
            "input_column": "voltage_V",
            "output_column": "displacement_mm",
            "sample_time_s": rec.dt,
            "n_samples": len(rec),
        },
    )
    return csv, fit_json


def test_cli_sample_end_to_end_and_resume(tmp_path, capsys):
    from smafl_jax.cli import main

    csv, fit_json = _write_fit(tmp_path)
    out = tmp_path / "out"
    args = [
        "sample",
        str(csv),
        "--fit",
        str(fit_json),
        "--out",
        str(out),
        "--steps",
        "60",
        "--walkers",
        "8",
        "--no-progress",
        "--draws",
        "20",
    ]
    assert main(args) == 0
    s = json.loads((out / "summary.json").read_text())
    assert set(s["parameters"]) == {"thermal.k1", "noise.sigma"}
    for p in s["parameters"].values():
        assert p["q025"] <= p["mean"] <= p["q975"] and p["sd"] > 0
    assert s["n_steps"] == 60 and 0 < s["acceptance_fraction"] < 1 and "thermal.k1" in s["autocorr_time"]
    assert s["derived"]["steady_state_gain"]["identified"] is False
    assert s["warnings"]  # 60 steps is too short, and says so
    for f in ("corner.png", "trace.png", "predictive_time.png", "predictive_loop.png", "parameters.csv", "chain.h5"):
        assert (out / f).stat().st_size > 0
    # same command with more steps extends the stored chain
    assert main([a if a != "60" else "80" for a in args]) == 0
    assert json.loads((out / "summary.json").read_text())["n_steps"] == 80
    assert "resuming" in capsys.readouterr().err
    # other settings on the same folder: refused without --restart
    assert main(args + ["--noise", "student-t"]) == 2
    assert "--restart" in capsys.readouterr().err
    assert main(["sample", str(csv), "--fit", str(fit_json), "--out", str(out), "--steps", "5"]) == 2


@pytest.mark.slow
def test_calibration_coverage_of_thermal_parameters():
    sys.path.insert(0, str(ROOT / "experiments"))
    import calibration

    res = calibration.run_joule(n_rep=60, n_steps=1500, seed=11, progress=False)
    for name in ("k1", "k2"):
        assert 0.8 <= res["coverage90"][name] <= 0.98, res["coverage90"]
