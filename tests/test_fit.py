"""Identification: recovery on synthetic data, solver agreement, failure messages, determinism, CLI."""

import json

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from reference import eupi_loop, random_reversals

import smafl_jax as sj
from smafl_jax.cli import main as cli_main


def _truth(datasets_dir):
    return sj.load_model_file(datasets_dir / "truth.json")


def _short_steps(datasets_dir, every=4):
    r = sj.load_record(datasets_dir / "steps.csv")
    return [(r.u[::every], r.y[::every], every * r.dt)]


def test_eupi_recovery_exact_linear(rng):
    """Noise-free EUPI data on its own grid: BVLS init + LM reproduce the output exactly.

    (The gains themselves are not unique for a given record: e.g. the largest-threshold operator
    and the polynomial can trade off, so only the output is compared.)"""
    base = sj.EUPI.from_range(0.0, 5.0, n_sym=4, n_alpha=2, n_asym=2, poly_order=2)
    truth = base.with_linear_weights(jnp.asarray([0.2, 1.0, 0.5, 0.3, 0.1, 0.4, 0.0, 0.2, 0.1, 0.7, -0.3]))
    u = random_reversals(rng, 600, 0.0, 5.0)
    y = eupi_loop(truth, u)  # numpy reference, independent of the JAX code
    res = sj.fit(base, (u, y), dt=1.0)
    assert res.converged, res.message
    yhat = np.asarray(sj.simulate(res.model, u))
    assert np.max(np.abs(yhat - y)) < 1e-6


def test_cascade_k1_recovery_and_noise_level(datasets_dir):
    """Cascade from the paper's thermal values: k1 within 2 %, output RMSE at the noise level (0.003 mm)."""
    truth, doc = _truth(datasets_dir)
    data = _short_steps(datasets_dir, every=2)
    res = sj.fit(sj.Cascade.from_range(7.4), data)
    assert res.converged, res.message
    k1 = float(res.model.thermal.k1)
    assert abs(k1 / float(truth.thermal.k1) - 1) < 0.02
    u, y, dt = data[0]
    rmse = sj.metrics(y, sj.simulate(res.model, u, dt))["rmse"]
    noise = doc["noise_sd_mm"]
    assert 0.8 * noise < rmse < 1.2 * noise
    # k2 is not identifiable in the cascade: it stays where it started
    assert float(res.model.thermal.k2) == pytest.approx(sj.PAPER_K2)


def test_cascade_output_independent_of_k2(datasets_dir):
    truth, _ = _truth(datasets_dir)
    u, _, dt = _short_steps(datasets_dir)[0]
    other = eqx.tree_at(lambda m: m.thermal.k2, truth, truth.thermal.k2 * 3.0)
    np.testing.assert_allclose(sj.simulate(truth, u, dt), sj.simulate(other, u, dt), rtol=1e-12, atol=1e-12)


def test_profile_beats_or_matches_grid(datasets_dir):
    model, info = sj.init_profile(sj.Cascade.from_range(7.4), _short_steps(datasets_dir), k1_grid=12)
    assert info["loss"] <= min(info["profile_loss"]) + 1e-12
    assert not info["at_grid_edge"]


# suite time: the optimistix Gauss-Newton and BFGS cases (10 s each) and jaxopt's L-BFGS-B (27 s) are slow; LM (optimistix)
# is the reference, and jaxopt's projected gradient (the same `_solve_jaxopt` path as L-BFGS-B) stays
@pytest.mark.parametrize(
    "solver",
    [
        pytest.param("gauss_newton", marks=pytest.mark.slow),
        pytest.param("bfgs", marks=pytest.mark.slow),
        pytest.param("lbfgsb", marks=pytest.mark.slow),
        "projected_gradient",
    ],
)
def test_solvers_agree_with_lm(solver, rng):
    """From the same linear start, every solver ends at the LM loss (within 1e-6 relative) on an EUPI problem."""
    base = sj.EUPI.from_range(0.0, 4.0, n_sym=3, n_alpha=2, n_asym=2, poly_order=2)
    truth = base.with_linear_weights(jnp.asarray([0.3, 1.0, 0.5, 0.2, 0.3, 0.1, 0.2, 0.1, 0.5, 0.1]))
    u = random_reversals(rng, 400, 0.0, 4.0)
    y = eupi_loop(truth, u) + 0.01 * rng.standard_normal(400)
    spec = sj.default_trainable(base, thresholds=True)
    ref = sj.fit(base, (u, y), dt=1.0, solver="lm", trainable=spec)
    res = sj.fit(base, (u, y), dt=1.0, solver=solver, trainable=spec, max_steps=2000)
    assert np.isfinite(res.loss)
    assert res.loss <= ref.loss * (1 + 1e-2) + 1e-12  # measured: within 0.2 % (gauss_newton), closer for the others
    assert res.loss <= res.init_loss * (1 + 1e-9)


def test_joule_lag_recovers_its_own_parameters(rng):
    """JouleLag (paper eq. 7) on data made by a JouleLag: K1, K2 and offset within 1 %."""
    true = sj.JouleLag(thermal=sj.JouleThermal(k1=jnp.asarray(0.05), k2=jnp.asarray(0.04)), offset=jnp.asarray(0.3))
    u = np.repeat([0.0, 2.0, 5.0, 3.0, 6.0, 1.0], 200)
    y = np.asarray(sj.simulate(true, u, 0.5)) + 0.003 * rng.standard_normal(u.size)
    res = sj.fit(sj.JouleLag(offset=jnp.asarray(0.0)), (u, y), dt=0.5)
    assert res.converged, res.message
    assert float(res.model.thermal.k1) == pytest.approx(0.05, rel=0.01)
    assert float(res.model.thermal.k2) == pytest.approx(0.04, rel=0.01)
    assert float(res.model.offset) == pytest.approx(0.3, abs=0.01)


def test_weights_exclude_samples(rng):
    """Samples with weight 0 do not influence the fit (gross outliers there change nothing)."""
    base = sj.EUPI.from_range(0.0, 4.0, n_sym=3, n_alpha=0, n_asym=0, poly_order=2)
    u = random_reversals(rng, 300, 0.0, 4.0)
    y = 0.5 * u + 0.01 * rng.standard_normal(300)
    w = np.ones(300)
    w[200:] = 0.0
    y_bad = y.copy()
    y_bad[200:] += 100.0
    a = sj.fit(base, (u, y), dt=1.0, weights=[w], solver=None)
    b = sj.fit(base, (u, y_bad), dt=1.0, weights=[w], solver=None)
    np.testing.assert_allclose(a.model.linear_weights(), b.model.linear_weights(), rtol=1e-9, atol=1e-12)


@pytest.mark.slow  # suite time (session 70: 15-260 s on 2 cores)
def test_deterministic(datasets_dir):
    data = _short_steps(datasets_dir, every=4)
    a = sj.fit(sj.Cascade.from_range(7.4), data, max_steps=20)
    b = sj.fit(sj.Cascade.from_range(7.4), data, max_steps=20)
    la = [np.asarray(x) for x in jax.tree_util.tree_leaves(a.model)]
    lb = [np.asarray(x) for x in jax.tree_util.tree_leaves(b.model)]
    assert all(np.array_equal(x, y) for x, y in zip(la, lb))
    assert a.loss == b.loss


@sj.register_model
class _NanAbove(eqx.Module):
    """Toy model y = a u that is NaN for a > 2 (to provoke a diverging refinement)."""

    a: jnp.ndarray

    def simulate(self, u, dt=None):
        return self.a * u + jnp.where(self.a > 2.0, jnp.nan, 0.0)


def test_nan_region_never_returned():
    """The optimum lies in a region where the model is NaN: the result stays finite."""
    u = np.linspace(0.0, 1.0, 50)
    res = sj.fit(_NanAbove(a=jnp.asarray(1.0)), (u, 3.0 * u), dt=1.0, init=None, solver="bfgs")
    assert np.isfinite(res.loss) and np.isfinite(float(res.model.a)) and float(res.model.a) <= 2.0


def test_divergence_is_reported_and_start_kept(monkeypatch):
    """A refinement that returns NaN is discarded with a message saying so and why."""
    from smafl_jax.identify import _fit  # private: monkeypatch target (_refine)

    def nan_refine(model, spec, args, solver, max_steps, rtol, atol, stall):
        return eqx.tree_at(lambda m: m.a, model, jnp.asarray(np.nan)), float("nan"), 7, False, False

    monkeypatch.setattr(_fit, "_refine", nan_refine)
    u = np.linspace(0.0, 1.0, 50)
    res = sj.fit(_NanAbove(a=jnp.asarray(1.0)), (u, 1.5 * u), dt=1.0, init=None)
    assert not res.converged
    assert "diverged" in res.message and "NaN" in res.message and "kept the initialiser" in res.message
    assert float(res.model.a) == 1.0 and np.isfinite(res.loss)


@pytest.mark.parametrize(("excess", "ok", "converged"), [(1e-4, True, True), (1e-2, True, False), (1e-4, False, False)])
def test_refinement_ending_just_above_the_start_keeps_it(monkeypatch, excess, ok, converged):
    """A solver that met its tolerance a hair above the initialiser's loss (it starts from lifted gains) keeps the
    initialiser and counts as converged; far above it, or without meeting its tolerance, it does not."""
    from smafl_jax.identify import _fit  # private: monkeypatch target (_refine)

    def worse_refine(model, spec, args, solver, max_steps, rtol, atol, stall):
        res = np.asarray(_fit._residuals_jit(model, args))
        moved = eqx.tree_at(lambda m: m.a, model, model.a + 0.5)
        return moved, 0.5 * float(res @ res) * (1 + excess), 9, ok, False

    monkeypatch.setattr(_fit, "_refine", worse_refine)
    u = np.linspace(0.0, 1.0, 50)
    res = sj.fit(_NanAbove(a=jnp.asarray(1.0)), (u, 1.5 * u), dt=1.0, init=None)
    assert res.converged is converged
    assert float(res.model.a) == 1.0 and res.loss == pytest.approx(res.init_loss, rel=1e-12)
    assert "kept the initialiser" in res.message
    assert ("converged" in res.message.split(":")[0]) is converged


def test_nan_at_start_raises_with_reason():
    u = np.linspace(0.0, 1.0, 50)
    with pytest.raises(sj.UserInputError, match="not finite at the start"):
        sj.fit(_NanAbove(a=jnp.asarray(3.0)), (u, u), dt=1.0, init=None)


def test_bad_arguments():
    u = np.linspace(0, 1, 20)
    m = sj.EUPI.from_range(0.0, 1.0)
    with pytest.raises(sj.UserInputError, match="unknown solver"):
        sj.fit(m, (u, u), dt=1.0, solver="newton")
    with pytest.raises(sj.UserInputError, match="init must be"):
        sj.fit(m, (u, u), dt=1.0, init="random")
    with pytest.raises(sj.UserInputError, match="weights"):
        sj.fit(m, (u, u), dt=1.0, weights=[np.ones(3)])
    with pytest.raises(sj.UserInputError, match="fewer than 3"):
        sj.fit(m, (u, u), dt=1.0, weights=[np.zeros(20)])


def test_split_rules():
    t = np.arange(100.0)
    rec = sj.Record.from_arrays(t, t, t, input_name="voltage_V", output_name="displacement")
    tr, va, info = sj.split_masks(rec)
    assert info["kind"] == "time" and va.sum() == 30 and va[-30:].all() and tr[:70].all()
    rec = sj.Record.from_arrays(t, t, t, input_name="voltage_V", output_name="displacement", extra={"branch": t // 10})
    tr, va, info = sj.split_masks(rec)
    assert info["validation_branches"] == [2.0, 5.0, 8.0]
    assert not (tr & va).any() and (tr | va).all()
    with pytest.raises(sj.UserInputError):
        sj.split_masks(rec, "time", val_fraction=1.5)


def test_fit_many_reports_failures(rng):
    base = sj.EUPI.from_range(0.0, 4.0, n_sym=2, n_alpha=0, n_asym=0, poly_order=1)
    u = random_reversals(rng, 100, 0.0, 4.0)
    out = sj.fit_many(base, [(u, u), (u[:2], u[:2])], dt=1.0, progress=False, max_steps=5)
    assert isinstance(out[0], sj.FitResult) and isinstance(out[1], sj.UserInputError)


def test_cli_fit_writes_fit_json_and_simulate_accepts_it(tmp_path, datasets_dir, capsys):
    r = sj.load_record(datasets_dir / "minor_loop.csv")
    data = tmp_path / "short.csv"
    sj.atomic_write_csv(data, {"time_s": r.time[::3], "voltage_V": r.u[::3], "displacement_mm": r.y[::3]})
    out = tmp_path / "fit"
    rc = cli_main(
        [
            "fit",
            str(data),
            "--model",
            "eupi",
            "--out",
            str(out),
            "--max-steps",
            "5",
            "--n-sym",
            "4",
            "--n-alpha",
            "2",
            "--n-asym",
            "2",
        ]
    )
    assert rc == 0
    doc = json.loads((out / "fit.json").read_text())
    for part in ("train", "validation"):
        assert set(doc["metrics"][part]) >= {"rmse", "e_r_percent", "max_abs_error", "mean_abs_error"}
    assert doc["data"]["sha256"] == sj.file_sha256(data)
    assert doc["data"]["input_column"] == "voltage_V" and doc["data"]["sample_time_s"] == pytest.approx(1.5)
    assert doc["model"]["type"] == "EUPI" and "versions" in doc and "settings" in doc
    # without --early-stopping the refinement runs whole: no early-stopping entry (tests/test_early_stopping.py: with it)
    assert doc["settings"]["early_stopping"] is False and doc["solver"]["early_stopping"] is None
    # errors in units of the output noise estimated from the data; a note (printed as a warning) above 2x on training
    noise = doc["metrics"]["noise"]
    assert noise["train_ratio"] == pytest.approx(doc["metrics"]["train"]["rmse"] / noise["sd"], rel=1e-12)
    assert noise["validation_ratio"] == pytest.approx(doc["metrics"]["validation"]["rmse"] / noise["sd"], rel=1e-12)
    assert any(n.startswith("above the noise floor") for n in doc["notes"]) == (noise["train_ratio"] > 2.0)
    assert f"({noise['train_ratio']:.3g}x noise)" in capsys.readouterr().out
    report = (out / "report.md").read_text()
    assert "RMSE / output noise SD" in report
    for f in ("fit_time.png", "fit_loops.png", "fit_residuals.png"):
        assert (out / f).exists() and f in report
    sim = tmp_path / "sim.csv"
    assert cli_main(["simulate", str(out / "fit.json"), str(data), "--out", str(sim)]) == 0
    y = np.loadtxt(sim, delimiter=",", skiprows=1)[:, 2]
    np.testing.assert_allclose(y, sj.simulate(sj.load_model(out / "fit.json"), r.u[::3]), rtol=1e-9)


def test_cli_fit_bad_inputs_exit_2(tmp_path, datasets_dir, capsys):
    data = datasets_dir / "steps.csv"
    assert cli_main(["fit", str(tmp_path / "missing.csv"), "--out", str(tmp_path / "o")]) == 2
    assert cli_main(["fit", str(data), "--output", "nope", "--out", str(tmp_path / "o")]) == 2
    assert cli_main(["fit", str(data), "--split", "branch", "--out", str(tmp_path / "o")]) == 2
    assert cli_main(["fit", str(data), "--max-steps", "-1", "--out", str(tmp_path / "o")]) == 2
    neg = tmp_path / "neg.csv"
    t = np.arange(50.0)
    sj.atomic_write_csv(neg, {"time_s": t, "voltage_V": np.sin(t), "displacement_mm": np.cos(t)})
    assert cli_main(["fit", str(neg), "--model", "cascade", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "drive voltage >= 0" in err and "goes down to -0.99" in err


@pytest.mark.slow
def test_real_forc_branch_split(real_data, tmp_path):
    """The real SMA FORC record fits (poorly, honestly) with validation on held-out branches."""
    out = tmp_path / "forc"
    assert (
        cli_main(["fit", str(real_data / "sma_wing_forc_train.csv"), "--model", "eupi", "--out", str(out), "--no-figures"]) == 0
    )
    doc = json.loads((out / "fit.json").read_text())
    assert doc["split"]["kind"] == "branch"
    assert np.isfinite(doc["metrics"]["validation"]["e_r_percent"])


def test_fit_data_accepts_two_records_and_is_idempotent(datasets_dir):
    """Two records (a 2-element list/tuple) are two records, not a (u, y) pair; normalising twice is a no-op."""
    recs = [sj.load_record(datasets_dir / "main_loop.csv"), sj.load_record(datasets_dir / "steps.csv")]
    once = sj.as_fit_data(recs)
    assert len(once) == 2 and once[1][0].shape == recs[1].u.shape
    twice = sj.as_fit_data(once)
    assert len(twice) == 2 and all(np.array_equal(a[0], b[0]) for a, b in zip(once, twice))
    assert len(sj.as_fit_data(tuple(recs))) == 2
    pair = sj.as_fit_data((recs[0].u, recs[0].y), dt=0.5)
    assert len(pair) == 1 and pair[0][2] == 0.5
    triple = sj.as_fit_data((recs[0].u, recs[0].y, 0.25))  # one (u, y, dt) triple
    assert len(triple) == 1 and triple[0][2] == 0.25 and np.array_equal(triple[0][1], recs[0].y)
    three = sj.as_fit_data(tuple(triple * 3))  # three triples stay three records
    assert len(three) == 3 and all(t[2] == 0.25 for t in three)


def test_fit_says_when_it_would_run_on_an_accelerator(monkeypatch):
    import jax

    from smafl_jax.cli.fit import _accelerator_note  # private: the CLI's note on the JAX backend

    assert _accelerator_note() is None  # the suite runs on the CPU
    monkeypatch.setattr(jax, "default_backend", lambda: "gpu")
    assert "JAX_PLATFORMS=cpu" in _accelerator_note()


@pytest.mark.slow  # suite time (session 70: 15-260 s on 2 cores)
def test_cli_fit_names_the_class_whose_refinement_did_not_converge(tmp_path, datasets_dir, capsys):
    """A refinement stopped by --max-steps is a warning that names the fitted class (with --model auto several are
    refined; a new-user trial read the kept one's message as a failure of the whole fit)."""
    r = sj.load_record(datasets_dir / "minor_loop.csv")
    data = tmp_path / "short.csv"
    sj.atomic_write_csv(data, {"time_s": r.time[::3], "voltage_V": r.u[::3], "displacement_mm": r.y[::3]})
    out = tmp_path / "fit"
    argv = ["fit", str(data), "--model", "eupi", "--thresholds", "--tilts", "--max-steps", "1", "--out", str(out)]
    assert cli_main([*argv, "--no-figures", "--n-sym", "4", "--n-alpha", "2", "--n-asym", "2"]) == 0
    doc = json.loads((out / "fit.json").read_text())
    assert doc["solver"]["converged"] is False
    assert f"warning: eupi: {doc['solver']['message']}" in capsys.readouterr().err
