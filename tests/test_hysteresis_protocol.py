"""The hysteresis protocol (`smafl_jax.models._hysteresis`): every registered model, parametrised from the registry.

Each concrete class (EUPI, Preisach, and any later one) must keep the contract the consumers rely on:
features @ weights == evaluation, step-scan == whole-record evaluation, weights round trip, fixed fields,
and it must work in fit, sampling, control and inside a cascade / extended model.  The CLI tests run the
user's path: ``smafl fit --model preisach`` -> ``control`` / ``sweep`` / ``sample``, and ``sample`` on an
``extended_fit.json`` as ``smafl diagnose`` writes it.
"""

import dataclasses
import json

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.bayes import Posterior
from smafl_jax.cli import main
from smafl_jax.control import PID, ClosedLoop, IICompensator, plant_init, plant_step, simulate_closed_loop, sine_reference
from smafl_jax.effects import EFFECTS, ExtendedModel
from smafl_jax.models import AbstractHysteresis, Preisach, hysteresis_models, hysteresis_of, relay_loop

MODELS = hysteresis_models()
IDS = [cls.__name__ for cls in MODELS]


def _example(cls, rng, *, init=None, orientation=1, u_max=3.5, **options):
    """A model of ``cls`` on ``[0, u_max]`` with random weights (>= 0 where required), small grid for speed."""
    small = {"EUPI": dict(n_sym=4, n_alpha=2, n_asym=3), "Preisach": dict(n_levels=6)}.get(cls.__name__, {})
    m = cls.from_range(0.0, u_max, init=init or cls.INITS[0], orientation=orientation, **{**small, **options})
    nonneg = np.asarray(m.nonnegative_columns())
    theta = np.where(nonneg, rng.uniform(0.0, 1.0, nonneg.size), rng.normal(0.0, 0.3, nonneg.size))
    return m.with_linear_weights(jnp.asarray(theta))


def _input(rng, u_max=3.5, n=300):
    """Starts mid-range (the init rules differ there) and wanders with reversals beyond both ends."""
    return jnp.asarray(np.concatenate([[0.45 * u_max], rng.uniform(-0.05 * u_max, 1.05 * u_max, n)]))


def _cases():
    """Every init rule of every model (orientation +1), and the falling orientation with the default init."""
    return [(cls, init, 1) for cls in MODELS for init in cls.INITS] + [(cls, cls.INITS[0], -1) for cls in MODELS]


@eqx.filter_jit
def _evaluations(m, u):
    """Whole-record output, features @ weights, the scan of `step`, the abstract scan, and the flipped features."""
    _, ys = jax.lax.scan(lambda st, x: m.step(st, x), m.initial_state(u[0]), u)
    flipped = dataclasses.replace(m, orientation=-m.orientation)
    return m.simulate(u), m(u), m.features(u), ys, AbstractHysteresis.simulate(m, u), flipped.features(u)


@pytest.mark.parametrize(("cls", "init", "orientation"), _cases(), ids=lambda x: getattr(x, "__name__", str(x)))
def test_features_step_and_evaluation_agree(cls, init, orientation, rng):
    m = _example(cls, rng, init=init, orientation=orientation)
    assert isinstance(m, AbstractHysteresis) and m.hysteresis is m and hysteresis_of(m) is m
    assert m.init == init and m.orientation == orientation
    u = _input(rng)
    y, y_call, F, ys, y_abstract, Ff = (np.asarray(x) for x in _evaluations(m, u))
    np.testing.assert_array_equal(y_call, y)
    np.testing.assert_allclose(F @ np.asarray(m.linear_weights()), y, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ys, y, rtol=0, atol=1e-12)
    np.testing.assert_allclose(y_abstract, y, rtol=0, atol=1e-12)  # the protocol's default evaluation: a scan of `step`
    # the orientation is the sign of the non-negative (hysteresis) part; the free columns (offset, polynomial) keep theirs
    nonneg = np.asarray(m.nonnegative_columns())
    np.testing.assert_array_equal(Ff[:, nonneg], -F[:, nonneg])
    np.testing.assert_array_equal(Ff[:, ~nonneg], F[:, ~nonneg])


@pytest.mark.parametrize("cls", MODELS, ids=IDS)
def test_linear_weights_round_trip_and_fields(cls, rng):
    m = _example(cls, rng)
    theta = np.asarray(m.linear_weights())
    p = theta.size
    assert np.asarray(m.features(_input(rng, n=20))).shape == (21, p)
    assert np.asarray(m.nonnegative_columns()).shape == (p,)
    new = rng.uniform(0.1, 1.0, p)
    back = m.with_linear_weights(jnp.asarray(new))
    np.testing.assert_array_equal(np.asarray(back.linear_weights()), new)
    np.testing.assert_array_equal(np.asarray(m.with_linear_weights(m.linear_weights()).linear_weights()), theta)
    with pytest.raises(ValueError, match="linear weights"):
        m.with_linear_weights(jnp.zeros(p + 1))
    names = {f.name for f in dataclasses.fields(m)}
    lin, fixed = set(m.linear_fields()), set(m.fixed_fields())
    assert lin <= names and fixed <= names and not lin & fixed
    # only the linear weights differ between two weight vectors
    diff = {
        f
        for f in names
        if eqx_array(getattr(m, f)) and not np.array_equal(np.asarray(getattr(m, f)), np.asarray(getattr(back, f)))
    }
    assert diff <= lin
    # default_trainable never trains a fixed field; every linear field is trained
    spec = sj.default_trainable(m)
    assert not any(np.any(getattr(spec, f)) for f in fixed)
    assert all(np.all(getattr(spec, f)) for f in lin)
    # the same structure on another range, and through JSON
    other = m.with_range(1.0, 2.0)
    assert type(other) is type(m) and np.asarray(other.linear_weights()).shape == (p,) and float(other.u_span) > 0
    again = sj.model_from_dict(json.loads(json.dumps(sj.to_jsonable(sj.model_to_dict(m)))))
    u = _input(rng, n=50)
    np.testing.assert_array_equal(np.asarray(again.simulate(u)), np.asarray(m.simulate(u)))


def eqx_array(x):
    return hasattr(x, "shape") and hasattr(x, "dtype")


@pytest.mark.parametrize("linear", [False, True])
@pytest.mark.parametrize("orientation", [1, -1])
def test_preisach_matches_numpy_loop_with_orientation(rng, linear, orientation):
    m = _example(Preisach, rng, linear=linear, orientation=orientation)
    u = np.asarray(_input(rng))
    a, b = (np.asarray(x) for x in m.thresholds())
    R = relay_loop(u, a, b, init_up=True, width=float(m.width))
    s = (u - float(m.u_ref)) / float(m.u_span)
    ref = orientation * (R @ np.asarray(m.w) + (float(m.gain) * s if linear else 0.0)) + float(m.offset)
    np.testing.assert_allclose(np.asarray(m.simulate(u)), ref, rtol=0, atol=1e-12)
    _, ys = jax.lax.scan(lambda st, x: m.step(st, x), m.initial_state(u[0]), jnp.asarray(u))
    np.testing.assert_allclose(np.asarray(ys), ref, rtol=0, atol=1e-12)


@pytest.mark.parametrize("cls", MODELS, ids=IDS)
def test_init_linear_recovers_output_and_cascade_uses_protocol(cls, rng):
    truth = _example(cls, rng)
    u = _input(rng, n=400)
    y = np.asarray(truth.simulate(u))
    start = truth.with_linear_weights(jnp.zeros_like(truth.linear_weights()))
    fitted = sj.init_linear(start, (np.asarray(u), y), 1.0)
    np.testing.assert_allclose(np.asarray(fitted.simulate(u)), y, atol=1e-7 * np.ptp(y))
    # inside a cascade: output == features @ weights, and the per-sample plant equals the open-loop record
    th = sj.JouleThermal(k1=0.1, k2=0.05)
    c = sj.Cascade(thermal=th, hysteresis=truth.with_range(0.0, 3.5).with_linear_weights(truth.linear_weights()))
    v = jnp.asarray(np.abs(np.asarray(_input(rng, n=200))))
    yc = np.asarray(c.simulate(v, 0.5))
    np.testing.assert_allclose(np.asarray(c.features(v, 0.5) @ c.hysteresis.linear_weights()), yc, atol=1e-12)
    _, yp = jax.lax.scan(lambda st, x: plant_step(c, st, x, jnp.asarray(0.5)), plant_init(c, v[0]), v)
    np.testing.assert_allclose(np.asarray(yp), yc, atol=1e-12)
    spec = sj.default_trainable(c)
    assert bool(spec.thermal.k1) and not bool(spec.thermal.k2)
    assert not any(np.any(getattr(spec.hysteresis, f)) for f in c.hysteresis.fixed_fields())


@pytest.mark.parametrize("cls", MODELS, ids=IDS)
def test_posterior_samples_only_weights_and_noise(cls, rng):
    m = _example(cls, rng)
    u = _input(rng, n=150)
    y = np.asarray(m.simulate(u)) + 0.01 * rng.standard_normal(u.shape[0])
    post = Posterior(m, (np.asarray(u), y), 1.0, linear="sample")
    shape = _always_trained_shape(m)  # a class whose shape is always trained (GaussianPreisach) samples it too
    expected = sorted([*m.linear_fields(), *shape])
    assert sorted({n.split("[")[0] for n in post.names_leaf} - {"noise.sigma"}) == expected
    assert post.names[-1] == "noise.sigma" and np.isfinite(post.log_prob(jnp.asarray(post.theta0)))
    assert all(post.priors[n].dist != "flat" for n in post.names_leaf)
    marg = Posterior(m, (np.asarray(u), y), 1.0, linear="marginalise")
    assert sorted({n.split("[")[0] for n in marg.names}) == sorted([*shape, "noise.sigma"])
    assert np.isfinite(marg.log_prob(jnp.asarray(marg.theta0)))


def _always_trained_shape(h):
    """Nonlinear fields a fit trains by default (not fixed, not linear weights), each with a prior of its own."""
    return [
        f
        for f in h.nonlinear_priors()
        if f not in h.fixed_fields() and f not in h.linear_fields() and getattr(h, f, None) is not None
    ]


@pytest.mark.parametrize("cls", MODELS, ids=IDS)
def test_extended_model_runs_any_hysteresis(cls, rng):
    m = _example(cls, rng)
    u = _input(rng, n=200)
    effects = (
        EFFECTS["input_warp"](c=jnp.asarray(0.1), b=jnp.asarray(1.5)),
        EFFECTS["creep"](g=jnp.asarray(0.1), tau=jnp.asarray(5.0)),
    )
    ext = ExtendedModel(m, effects)
    assert ext.hysteresis is m and ext.linear_in_weights
    y = np.asarray(ext.simulate(u, 0.5))
    np.testing.assert_allclose(np.asarray(ext.features(u, 0.5) @ m.linear_weights()), y, atol=1e-12)
    # no effect: the extended model is its base
    np.testing.assert_allclose(np.asarray(ExtendedModel(m, ()).simulate(u, 0.5)), np.asarray(m.simulate(u)), atol=1e-12)
    swapped = ext.with_hysteresis(m.with_linear_weights(2.0 * m.linear_weights()))
    assert np.allclose(np.asarray(swapped.hysteresis.linear_weights()), 2.0 * np.asarray(m.linear_weights()))
    if not cls.scalable_thresholds:
        with pytest.raises(ValueError, match="rate_dependence"):
            ExtendedModel(m, (EFFECTS["rate_dependence"](c=jnp.asarray(0.1)),))


@pytest.mark.parametrize("cls", MODELS, ids=IDS)
def test_closed_loop_with_any_hysteresis_plant_and_compensator(cls, rng):
    m = _example(cls, rng, u_max=7.4)
    ref = sine_reference(3.0, 0.05, amplitude=0.2, offset=float(np.mean(np.asarray(m.simulate(jnp.linspace(0, 7.4, 50))))))
    loop = ClosedLoop(plant=m, pid=PID(kp=0.5, ki=2.0), reference=jnp.asarray(ref), compensator=IICompensator(m, 2.0))
    metrics, traj = simulate_closed_loop(loop, 0.05)
    assert all(np.isfinite(float(v)) for v in metrics.values())
    # the plant output is the model's open-loop response to the drive the loop applied (zero-order hold: y(k+1) <- u(k))
    u = np.asarray(traj["u"])
    y_open = np.asarray(m.simulate(jnp.asarray(np.concatenate([[0.0], u[:-1]]))))
    np.testing.assert_allclose(np.asarray(traj["y"]), y_open, atol=1e-12)
    falling = dataclasses.replace(m, orientation=-1)
    assert float(IICompensator(falling).forward_model.hysteresis.orientation) == -1.0


# -- the user's path through the CLI -------------------------------------------------------------------


def _short_record(tmp_path, datasets_dir, n=400):
    d = np.genfromtxt(datasets_dir / "main_loop.csv", delimiter=",", names=True)[:n]
    path = tmp_path / "rec.csv"
    sj.atomic_write_csv(path, {"time_s": d["time_s"], "voltage_V": d["voltage_V"], "displacement_mm": d["displacement_mm"]})
    return path


@pytest.mark.slow  # suite time (10-minute budget): 27 s; the EUPI fit -> control -> sweep -> sample chain runs in test_workflows_cli.py
def test_cli_fit_preisach_then_control_sweep_and_sample(tmp_path, datasets_dir, capsys):
    record = datasets_dir / "main_loop.csv"
    fit_dir = tmp_path / "fit"
    assert main(["fit", str(record), "--model", "preisach", "--max-steps", "0", "--no-figures", "--out", str(fit_dir)]) == 0
    doc = json.loads((fit_dir / "fit.json").read_text())
    assert doc["model"]["type"] == "Preisach" and doc["settings"]["structure"] == "preisach"
    assert np.isfinite(doc["metrics"]["validation"]["rmse"]) and min(doc["model"]["w"]) >= 0.0
    model, _ = sj.load_model_file(fit_dir / "fit.json")
    # held out (the last 30 %), the loop is predicted to a small fraction of the output's spread
    assert doc["metrics"]["validation"]["rmse"] < 0.2 * np.std(
        np.genfromtxt(record, delimiter=",", names=True)["displacement_mm"]
    )
    rec = _short_record(tmp_path, datasets_dir)
    fit = str(fit_dir / "fit.json")
    loop = ["--model", fit, "--kp", "0.5", "--ki", "2", "--K", "2", "--duration", "4", "--dt", "0.05"]
    assert main(["control", *loop, "--out", str(tmp_path / "c")]) == 0
    metrics = json.loads((tmp_path / "c" / "metrics.json").read_text())
    assert np.isfinite(metrics["e_mean_mm"]) and metrics["settings"]["compensator_forward_model"] == "static Preisach"
    # the fit's training range travels with the plant, so the control drive is checked against it
    assert metrics["settings"]["plant_fitted_ranges"]["input_range"] == doc["data"]["input_range"]
    assert metrics["range_checks"][0]["checked"]
    assert main(["sweep", *loop, "--x", "kp=0.2:1:2", "--y", "K=0,2", "--out", str(tmp_path / "sw")]) == 0
    assert (tmp_path / "sw" / "sweep.csv").exists()
    capsys.readouterr()
    # sampling: only the noise is sampled, the relay weights are marginalised (auto); grids never appear
    args = ["sample", str(rec), "--fit", fit, "--steps", "12", "--walkers", "4", "--draws", "4", "--no-progress"]
    assert main([*args, "--out", str(tmp_path / "s")]) == 0
    summary = json.loads((tmp_path / "s" / "summary.json").read_text())
    assert list(summary["parameters"]) == ["noise.sigma"] and summary["settings"]["linear"] == "marginalise"
    assert model.n_relays > 100  # the default grid: sampling its weights explicitly is left to small grids (below)


@pytest.mark.slow  # ~7 s: the explicit (non-marginalised) weights; the default path is tested above
def test_cli_sample_preisach_weights_explicitly(tmp_path, datasets_dir):
    rec = _short_record(tmp_path, datasets_dir, n=200)
    d = np.genfromtxt(rec, delimiter=",", names=True)
    m = Preisach.from_range(0.0, float(d["voltage_V"].max()), n_levels=3)
    m = sj.init_linear(m, (d["voltage_V"], d["displacement_mm"]), 0.5)
    sj.save_model(tmp_path / "small.json", m)
    args = ["sample", str(rec), "--fit", str(tmp_path / "small.json"), "--linear", "sample", "--steps", "12", "--draws", "4"]
    assert main([*args, "--walkers", "16", "--no-progress", "--out", str(tmp_path / "s")]) == 0
    names = list(json.loads((tmp_path / "s" / "summary.json").read_text())["parameters"])
    assert names == [f"w[{i}]" for i in range(6)] + ["offset", "noise.sigma"]


@pytest.mark.slow  # suite time (10-minute budget): 17 s; `smafl sample` end to end runs in test_bayes.py
def test_cli_sample_on_an_extended_fit(tmp_path, datasets_dir, capsys):
    rec = _short_record(tmp_path, datasets_dir, n=200)
    truth = sj.load_model(datasets_dir / "truth.json")
    ext = ExtendedModel(truth, (EFFECTS["delay"](tau=jnp.asarray(0.6)),))
    sj.save_model(tmp_path / "extended_fit.json", ext)  # the format `smafl diagnose` writes
    args = ["sample", str(rec), "--fit", str(tmp_path / "extended_fit.json"), "--steps", "12", "--walkers", "8", "--draws", "4"]
    assert main([*args, "--no-progress", "--out", str(tmp_path / "s")]) == 0
    assert "Traceback" not in capsys.readouterr().err
    summary = json.loads((tmp_path / "s" / "summary.json").read_text())
    assert list(summary["parameters"]) == ["base.thermal.k1", "effects[0].tau", "noise.sigma"]
    assert summary["settings"]["priors"]["base.thermal.k1"]["dist"] == "lognormal"
    assert "time_constant_s" in summary["derived"]


def test_thermal_of_names_the_stage_in_front_of_the_hysteresis():
    """`thermal_of` answers "is there a thermal lag in front of the hysteresis?" for every model kind, so callers
    ask the model instead of testing its class (issue 12)."""
    from smafl_jax.effects import ExtendedModel

    h = sj.EUPI.from_range(0.0, 1.0)
    th = sj.JouleThermal()
    casc = sj.Cascade(thermal=th, hysteresis=h)
    assert sj.thermal_of(casc) is th and sj.thermal_of(ExtendedModel(casc, ())) is th
    assert sj.thermal_of(h) is None and sj.thermal_of(ExtendedModel(h, ())) is None
    assert sj.thermal_of(sj.JouleLag()) is None and sj.thermal_of(th) is None
