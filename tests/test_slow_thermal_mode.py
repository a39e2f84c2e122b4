"""The optional slow thermal mode of `JouleThermal` (``slow_k1``, ``slow_ratio``) and `--model auto`'s check that
tries it (`_report_fit._slow_mode_check`): against a plain numpy loop, in every place a cascade runs (simulate, the
extended model, the closed-loop plant step), its gradients, saving, recovery of known values, and the check's rule."""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.control import plant_init, plant_step
from smafl_jax.report import _report_fit  # private: choose_structure with stand-in candidates

DT = 0.1


def _drive(seed=0, n=1500):
    rng = np.random.default_rng(seed)
    return np.repeat(rng.uniform(0.0, 5.0, n // 50), 50)


def _numpy_thermal(u, dt, k1, k2, ks, r, theta0, lag=0):
    """Plain loop: the slow mass low-passes U^2, the wire relaxes to (U^2 + r z) / (1 + r); both start at theta0."""
    g = k2 / k1
    a, a_s = np.exp(-k1 * dt), np.exp(-ks * dt)
    v = np.concatenate([u[:1], u[:-1]]) if lag else u
    theta, z, out = theta0, theta0 / g, []
    for vk in v:
        z = a_s * z + (1 - a_s) * vk * vk
        theta = a * theta + (1 - a) * g * (vk * vk + r * z) / (1 + r)
        out.append(theta)
    return np.array(out)


@pytest.mark.parametrize("init,u0", [("steady", None), ("ambient", None), ("given", 1.7)])
@pytest.mark.parametrize("lag", [0, 1])
def test_matches_a_numpy_loop(init, u0, lag):
    u = _drive()
    th = sj.JouleThermal(k1=0.3, k2=0.12, init=init, u0=u0, lag=lag).with_slow_mode(0.01, 0.6)
    g = 0.12 / 0.3
    theta0 = {"steady": g * u[0] ** 2, "ambient": 0.0, "given": g * 1.7**2}[init]
    want = _numpy_thermal(u, DT, 0.3, 0.12, 0.01, 0.6, theta0, lag)
    np.testing.assert_allclose(np.asarray(th.simulate(u, DT)), want, rtol=1e-12, atol=1e-12)


def test_steady_state_and_no_slow_mode_unchanged():
    u = np.full(20000, 3.0)
    th = sj.JouleThermal(k1=0.3, k2=0.12, init="ambient").with_slow_mode(0.02, 1.0)
    theta = np.asarray(th.simulate(u, DT))
    assert theta[-1] == pytest.approx(float(th.gain) * 9.0, rel=1e-6)  # the slow mode leaves the steady state where it was
    # the slow mass holds the wire back: half-way to steady state later than one mode alone
    one = np.asarray(sj.JouleThermal(k1=0.3, k2=0.12, init="ambient").simulate(u, DT))
    assert np.argmax(theta > 0.9 * theta[-1]) > 3 * np.argmax(one > 0.9 * one[-1])
    assert not sj.JouleThermal().has_slow_mode and sj.JouleThermal().slow_k1 is None


def test_needs_both_fields():
    with pytest.raises(ValueError, match="slow_k1 and slow_ratio together"):
        sj.JouleThermal(slow_k1=0.01)


def _cascade(seed=1):
    h = sj.EUPI.from_range(0.0, 5.0)
    w = np.abs(np.random.default_rng(seed).normal(size=h.linear_weights().shape))
    th = sj.JouleThermal(k1=0.3, k2=0.12).with_slow_mode(0.01, 0.5)
    return sj.Cascade(thermal=th, hysteresis=h.with_linear_weights(jnp.asarray(w)))


def test_every_runner_of_a_cascade_agrees():
    m, u = _cascade(), _drive(2, 600)
    y = np.asarray(sj.simulate(m, u, DT))
    assert np.ptp(y) > 1.0
    # the extended model (diagnosis) runs its own thermal loop: it takes the slow mode through `JouleThermal.heat`
    np.testing.assert_allclose(np.asarray(sj.ExtendedModel(m, ()).simulate(u, DT)), y, rtol=0, atol=1e-10)
    # the closed-loop plant, one sample at a time
    state, ys = plant_init(m, u[0]), []
    step = jax.jit(lambda s, uk: plant_step(m, s, uk, DT))
    for uk in u:
        state, yk = step(state, jnp.asarray(uk))
        ys.append(float(yk))
    np.testing.assert_allclose(ys, y, rtol=0, atol=1e-10)


def test_gradients_match_finite_differences():
    u = _drive(3, 400)
    w = jnp.asarray(np.random.default_rng(0).normal(size=400))

    def loss(ks, r):
        th = sj.JouleThermal(k1=0.3, k2=0.12, init="ambient").with_slow_mode(1.0, 1.0)
        th = eqx.tree_at(lambda t: (t.slow_k1, t.slow_ratio), th, (ks, r))
        return jnp.sum(w * th.simulate(u, DT))

    ks, r = 0.02, 0.7
    g = jax.grad(loss, argnums=(0, 1))(jnp.asarray(ks), jnp.asarray(r))
    for i, (x, h) in enumerate(((ks, 1e-6), (r, 1e-6))):
        args = [ks, r]
        args[i] = x + h
        up = float(loss(*map(jnp.asarray, args)))
        args[i] = x - h
        fd = (up - float(loss(*map(jnp.asarray, args)))) / (2 * h)
        assert float(g[i]) == pytest.approx(fd, rel=1e-5)


def test_saved_and_loaded(tmp_path):
    m = _cascade()
    back = sj.model_from_dict(sj.model_to_dict(m))
    assert float(back.thermal.slow_k1) == 0.01 and float(back.thermal.slow_ratio) == 0.5
    one = sj.model_from_dict(sj.model_to_dict(dataclasses.replace(m, thermal=sj.JouleThermal())))
    assert one.thermal.slow_k1 is None  # a model without the slow mode (every fit.json before it) loads as before
    assert any("slow thermal mode" in line for line in m.thermal.describe())


def test_sampler_priors_cover_the_slow_mode(stand_in_record):
    from smafl_jax.bayes import default_priors

    names = ["thermal.slow_k1", "base.thermal.slow_ratio"]
    r = stand_in_record
    priors = default_priors(names, [(r.u, r.y, r.dt)])
    assert all(priors[n].dist == "lognormal" for n in names)  # not flat: a rate and a ratio have a scale


@pytest.mark.slow  # suite time (session 71: 31 s under load); the slow mode's numpy loop and gradients stay in the default suite
def test_fit_recovers_a_known_slow_mode():
    # a record made with known rates; the fit starts from another slow mode and trains it with the rest
    truth = _cascade()
    u = _drive(4, 6000)
    rec = sj.Record.from_arrays(np.arange(6000) * DT, u, np.asarray(sj.simulate(truth, u, DT)))
    start = eqx.tree_at(lambda m: (m.thermal.slow_k1, m.thermal.slow_ratio), truth, (jnp.asarray(0.02), jnp.asarray(0.3)))
    start = eqx.tree_at(lambda m: m.thermal.k1, start, jnp.asarray(0.2))
    res = sj.fit(start, rec, init="linear", max_steps=200)
    th = res.model.thermal
    assert float(th.slow_k1) == pytest.approx(0.01, rel=0.02)
    assert float(th.slow_ratio) == pytest.approx(0.5, rel=0.02)
    assert float(th.k1) == pytest.approx(0.3, rel=0.02)


@pytest.mark.slow  # suite time (session 70: 15-260 s on 2 cores)
def test_a_slow_mode_added_to_a_one_mode_fit_nests_it():
    # the check's fits start from each class's one-mode fit (`slow_warm_start`): the search with the slow mode cannot
    # end above the one-mode fit on its own samples, and on a record with a slow mode it finds it
    truth = _cascade()
    u = _drive(5, 6000)
    rec = sj.Record.from_arrays(np.arange(6000) * DT, u, np.asarray(sj.simulate(truth, u, DT)))
    one = dataclasses.replace(truth, thermal=sj.JouleThermal(k1=0.2, k2=0.12))
    one = sj.fit(one, rec, init="linear", max_steps=100).model
    ones = [np.ones(6000)]
    warm = _report_fit.slow_warm_start(one, rec, ones)
    assert warm.thermal.has_slow_mode and warm.thermal.init == "given"

    def loss(m):
        return float(sj.fit(m, rec, solver=None, init=None, weights=ones).loss)

    assert loss(warm) < 1e-3 * loss(one)
    th = warm.thermal  # truth: 0.01 1/s and ratio 0.5, searched from 1/120 1/s and 0.05; k1 0.3 (one-mode fit 0.19)
    assert (float(th.slow_k1), float(th.slow_ratio), float(th.k1)) == pytest.approx((0.01, 0.5, 0.3), rel=0.05)


@pytest.mark.slow  # suite time (session 70: 15-260 s on 2 cores)
def test_the_search_keeps_the_slow_mode_slower_than_the_wire():
    # a record whose second lag is faster than the wire (a series lag, not a slower mass): the search stays where the
    # mode is slower than the wire, so it is never reported as a slow thermal mode
    truth = dataclasses.replace(_cascade(), thermal=sj.JouleThermal(k1=0.3, k2=0.12).with_slow_mode(3.0, 50.0))
    u = _drive(6, 3000)
    rec = sj.Record.from_arrays(np.arange(3000) * DT, u, np.asarray(sj.simulate(truth, u, DT)))
    one = sj.fit(dataclasses.replace(truth, thermal=sj.JouleThermal(k1=0.3, k2=0.12)), rec, init="linear", max_steps=50)
    warm = _report_fit.slow_warm_start(one.model, rec, [np.ones(3000)])
    assert float(warm.thermal.slow_k1) < float(warm.thermal.k1)


def test_a_warm_start_needs_the_slow_mode(stand_in_record):
    with pytest.raises(ValueError, match="needs slow_mode"):
        _report_fit._fit_structure(stand_in_record, model="cascade", warm_start=_cascade())


def test_unknown_slow_mode_option(stand_in_record):
    with pytest.raises(sj.UserInputError, match="unknown slow_mode"):
        _report_fit.fit_record(stand_in_record, slow_mode="yes")


# -- the check of --model auto (stand-in candidates, as tests/test_whole_record_check.py) ---------------------------


def _stand_ins(record, val, whole, noise_sd=0.01, faster=()):
    """`fit_one` stand-ins: fixed validation and whole-record RMSEs per class, ``"+slow"`` for a fit with the slow mode."""
    calls, models, warm = [], {}, {}

    def fit_one(name, options):
        key = name + ("+slow" if options.get("slow_mode") else "") + ("+warm" if options.get("warm_start") else "")
        model = _report_fit.build_model("cascade", record)
        if options.get("slow_mode"):  # 10x slower than the wire; 10x faster: a refinement that made it faster
            th = model.thermal
            model = dataclasses.replace(model, thermal=th.with_slow_mode((10 if key in faster else 0.1) * float(th.k1), 0.3))
        models[key] = model
        warm[key] = options.get("warm_start")
        v = val.get(key, 1.1 * val[key.removesuffix("+warm")])  # from the one-mode fit: worse unless said
        m = {"validation": {"rmse": v, "e_r_percent": 10 * v}, "train": {"rmse": v / 2}}

        def finish():
            calls.append(key)
            noise = {"sd": noise_sd, "whole_record_ratio": whole[key] / noise_sd}
            metrics = {**m, "whole_record": {"rmse": whole[key]}, "noise": noise}
            doc = {"settings": {"structure": key}, "notes": [f"refit of {key}"], "metrics": metrics, "data": {}}
            return model, doc, (np.ones(len(record), bool), np.zeros(len(record), bool), None)

        return _report_fit.Candidate(model, m, None, finish, None)

    fit_one.models, fit_one.warm = models, warm  # what each fit returned, and the warm start it was given
    return fit_one, calls


def _choose(record, monkeypatch, val, whole, faster=()):
    monkeypatch.setattr(_report_fit, "candidate_threads", lambda k: 1)
    fit_one, calls = _stand_ins(record, val, whole, faster=faster)
    final, doc, _ = _report_fit.choose_structure(record, fit_one, {}, progress=False, slow_check=True)
    # a fit with a slow mode starts fresh or from its own class's one-mode fit
    for key, start in fit_one.warm.items():
        assert start is (fit_one.models[key.removesuffix("+slow+warm")] if key.endswith("+warm") else None)
    assert {k for k in fit_one.warm if k.endswith("+warm")} == {k + "+warm" for k in fit_one.warm if k.endswith("+slow")}
    return final, doc, calls


VAL = {"auto": 0.1, "cascade-preisach-gauss": 0.2, "cascade-phase": 0.3}
WHOLE = {"auto": 0.05, "cascade-preisach-gauss": 0.06, "cascade-phase": 0.07}  # none 2x ahead: no class switch
SLOW_VAL = {"auto+slow": 0.09, "cascade-preisach-gauss+slow": 0.15, "cascade-phase+slow": 0.2}
SLOW_WHOLE = {"auto+slow": 0.02, "cascade-preisach-gauss+slow": 0.03, "cascade-phase+slow": 0.01}


def test_the_class_best_with_a_slow_mode_is_kept(stand_in_record, monkeypatch):
    # with a slow mode the phase class wins the validation block by more than the margin
    val = {**VAL, **SLOW_VAL, "cascade-phase+slow": 0.05}
    final, doc, calls = _choose(stand_in_record, monkeypatch, val, {**WHOLE, **SLOW_WHOLE})
    choice = doc["settings"]["structure_choice"]
    check = choice["slow_mode_check"]
    assert check["kept"] and check["class"] == "cascade-phase"
    assert check["validation_rmse"] == {"without": 0.1, "cascade": 0.09, "cascade-preisach-gauss": 0.15, "cascade-phase": 0.05}
    assert check["whole_record_rmse"] == {"without": 0.05, "with": 0.01}
    assert choice["chosen"] == "cascade-phase + slow thermal mode" and final.thermal.has_slow_mode
    assert doc["settings"]["structure"] == "cascade-phase+slow" and calls.count("cascade-phase+slow") == 1
    assert "slow thermal mode" in doc["notes"][0]
    assert check["starts"]["cascade-phase"] == {"fresh": 0.05, "one_mode_fit": pytest.approx(0.055)}


def test_the_start_from_the_one_mode_fit_wins_where_it_is_lower(stand_in_record, monkeypatch):
    val = {**VAL, **SLOW_VAL, "cascade-preisach-gauss+slow+warm": 0.04}
    whole = {**WHOLE, **SLOW_WHOLE, "cascade-preisach-gauss+slow+warm": 0.005}
    final, doc, calls = _choose(stand_in_record, monkeypatch, val, whole)
    check = doc["settings"]["structure_choice"]["slow_mode_check"]
    assert check["kept"] and check["class"] == "cascade-preisach-gauss" and "from its one-mode fit" in check["note"]
    assert check["validation_rmse"]["cascade-preisach-gauss"] == 0.04 and check["whole_record_rmse"]["with"] == 0.005
    assert [c for c in calls if "+slow" in c] == ["cascade-preisach-gauss+slow+warm"]  # only the winner is refitted


@pytest.mark.parametrize(
    "best_val,best_whole,why",
    [(0.09, 0.02, "validation not lower by more than"), (0.05, 0.06, "whole record not lower")],
)
def test_a_slow_mode_that_does_not_predict_better_is_not_kept(stand_in_record, monkeypatch, best_val, best_whole, why):
    val, whole = {**VAL, **SLOW_VAL, "auto+slow": best_val}, {**WHOLE, **SLOW_WHOLE, "auto+slow": best_whole}
    final, doc, calls = _choose(stand_in_record, monkeypatch, val, whole)
    check = doc["settings"]["structure_choice"]["slow_mode_check"]
    assert not check["kept"] and why in check["note"]
    assert doc["settings"]["structure"] == "auto" and not final.thermal.has_slow_mode


def test_a_slow_mode_faster_than_the_wire_does_not_count(stand_in_record, monkeypatch):
    # the phase class's fits are lowest on validation, but their refinements made the "slow" mode 10x faster than the wire
    val = {**VAL, **SLOW_VAL, "cascade-phase+slow": 0.01}
    final, doc, calls = _choose(
        stand_in_record, monkeypatch, val, {**WHOLE, **SLOW_WHOLE}, faster=("cascade-phase+slow", "cascade-phase+slow+warm")
    )
    check = doc["settings"]["structure_choice"]["slow_mode_check"]
    assert check["starts"]["cascade-phase"] == {"fresh": None, "one_mode_fit": None} and check["class"] == "cascade"
    assert not check["kept"] and not final.thermal.has_slow_mode


def test_a_fit_near_the_noise_tries_no_slow_mode(stand_in_record, monkeypatch):
    near = {k: 0.015 for k in WHOLE}
    _, doc, calls = _choose(stand_in_record, monkeypatch, {**VAL, **SLOW_VAL}, {**near, **SLOW_WHOLE})
    assert "slow_mode_check" not in doc["settings"]["structure_choice"]
    assert not any(c.endswith("+slow") for c in calls)


def test_cli_flag_reaches_the_fit():
    from smafl_jax.cli import build_parser
    from smafl_jax.cli.fit import record_fit_options

    parse = build_parser("fit").parse_args
    assert record_fit_options(parse(["fit", "x.csv"]), progress=False)["slow_mode"] == "auto"
    assert record_fit_options(parse(["fit", "x.csv", "--slow-mode", "off"]), progress=False)["slow_mode"] == "off"
    with pytest.raises(Exception, match="invalid choice: 'sometimes'"):
        parse(["fit", "x.csv", "--slow-mode", "sometimes"])
