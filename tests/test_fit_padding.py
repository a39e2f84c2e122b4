"""`fit` pads each record at its end to a bucket length with weight 0, so nearby lengths share compiled programs.

- The fit is the one without padding: same parameters, loss and noise ratio, with a validation mask as weights (the
  profile initialiser, a refinement that moves; a joint fit of two records of different lengths, each from its own
  thermal start and memory rule: bounded least squares, the gain prior, and in the slow test the refinement).
- Another length in the same bucket compiles none of the fit's programs again.
"""

import sys
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.models import bucket_length

sys.path.insert(0, str(Path(__file__).parent))
import indep_plant
from compile_log import compiled_names

#: The fit's programs that see per-sample arrays (`identify._fit`): the residuals, the solver, the designs.
FIT_PROGRAMS = ("_residuals", "_solve_optx", "_features", "_batch_design")


def _records(lengths, seed=40):
    """Records of ``lengths`` samples of one independent plant (10 Hz, other drives) and a small cascade template."""
    recs = [
        indep_plant.make_record(
            seed, drive="multisine", rate_hz=10.0, minutes=n / 600.0, start="cold", orientation="displacement"
        )
        for n in lengths
    ]
    assert [r["u"].size for r in recs] == list(lengths)
    u_max = max(float(np.max(r["u"])) for r in recs)
    model = sj.Cascade.from_range(u_max, n_sym=4, n_alpha=2, n_asym=2).with_thermal_start("ambient")
    return [(r["u"], r["y"], r["dt"]) for r in recs], model


def _joint(lengths, seed=40):
    """`_records` and a template that starts each record its own way (thermal state and operator memory)."""
    data, model = _records(lengths, seed)
    return data, model.with_record_starts([0.0, 0.1], inits=("descended", "from_top"))


def _params(model):
    return np.concatenate(
        [np.ravel(np.asarray(x, dtype=np.float64)) for x in jax.tree_util.tree_leaves(model) if hasattr(x, "dtype")]
    )


def _same_fit(a, b, rtol=1e-8):
    pa, pb = _params(a.model), _params(b.model)
    np.testing.assert_allclose(pb, pa, rtol=rtol, atol=1e-12 * float(np.max(np.abs(pa))))
    assert b.loss == pytest.approx(a.loss, rel=1e-12)
    assert b.init_loss == pytest.approx(a.init_loss, rel=1e-12)
    assert (b.converged, b.solver) == (a.converged, a.solver)
    ia, ib = a.info or {}, b.info or {}
    assert set(ia) == set(ib)
    if ia.get("refinement_lowered_loss"):  # (a refinement from an optimum takes steps that round-off decides)
        assert b.n_steps == a.n_steps
    for key in ("train_noise_ratio", "refinement_lowered_loss"):  # the noise ratio: of the records as given
        if key in ia:
            assert ib[key] == pytest.approx(ia[key], rel=1e-10)
    if "profile" in ia:
        assert ib["profile"]["k1_grid"] == ia["profile"]["k1_grid"]  # from the records' own durations
        np.testing.assert_allclose(ib["profile"]["profile_loss"], ia["profile"]["profile_loss"], rtol=1e-10)
    if "gain_prior" in ia:
        for key in ("sigma", "output_range", "rmse", "rmse_free", "largest_gain"):
            assert ib["gain_prior"][key] == pytest.approx(ia["gain_prior"][key], rel=1e-10)


def _gains_only(model):
    spec = jax.tree_util.tree_map(lambda _: False, sj.default_trainable(model))
    fields = model.hysteresis.linear_fields()
    return eqx.tree_at(lambda s: [getattr(s.hysteresis, f) for f in fields], spec, [True] * len(fields))


@pytest.mark.slow  # suite time (11 s): the padded joint fit (bounded least squares, gain prior) stays in the default suite
def test_padded_fit_is_the_unpadded_fit():
    (rec,), model = _records((601,))
    assert bucket_length(601) > 601
    weights = [(np.arange(601) < 420).astype(float)]  # the last 30 % held out (the split fit's mask)
    # the profile initialiser (k1 grid from the record's duration) and its refinement: the noise ratio is reported
    r0, r1 = (sj.fit(model, rec, weights=weights, max_steps=10, pad=p) for p in (False, True))
    assert "train_noise_ratio" in r0.info
    _same_fit(r0, r1)


@pytest.mark.slow  # suite time (10 s): the refinement's padded program is checked in the default suite above
def test_padded_refinement_that_moves_is_the_unpadded_one():
    (rec,), model = _records((601,))
    weights = [(np.arange(601) < 420).astype(float)]
    # a refinement that moves (from the template's own k1 and gains; the same program)
    m0, m1 = (sj.fit(model, rec, weights=weights, init=None, max_steps=10, pad=p) for p in (False, True))
    assert m0.n_steps > 5 and m0.info["refinement_lowered_loss"]
    _same_fit(m0, m1)


def test_padded_joint_fit_keeps_each_record_start():
    data, model = _joint((601, 703))
    assert all(bucket_length(u.size) > u.size for u, _, _ in data)  # both records are padded
    weights = [(np.arange(601) < 420).astype(float), None]
    # bounded least squares for the gains, each record from its own start (the loss runs through `record_model`)
    r0, r1 = (sj.fit(model, data, weights=weights, init="linear", solver=None, pad=p) for p in (False, True))
    _same_fit(r0, r1)
    # the gain prior's MAP gains (rows counted, range and noise of the given samples)
    g0, g1 = (sj.fit(r0.model, data, weights=weights, init=None, solver=None, gain_prior=0.1, pad=p) for p in (False, True))
    assert g0.info["gain_prior"]["largest_gain"] < g0.info["gain_prior"]["largest_gain_free"]  # the prior acts
    _same_fit(g0, g1)


@pytest.mark.slow
def test_padded_joint_refinement_is_the_unpadded_one():
    data, model = _joint((601, 703))
    weights = [(np.arange(601) < 420).astype(float), None]
    # profile, then a refinement that moves the per-record thermal starts too
    r0, r1 = (sj.fit(model, data, weights=weights, max_steps=10, pad=p) for p in (False, True))
    assert r0.n_steps > 5 and r0.info["refinement_lowered_loss"]
    _same_fit(r0, r1)
    # the gains alone after bounded least squares: the refinement cannot lower the loss, the noise ratio is reported
    m0, m1 = (sj.fit(r0.model, data, weights=weights, trainable=_gains_only(model), init="linear", pad=p) for p in (False, True))
    assert "train_noise_ratio" in m0.info
    _same_fit(m0, m1)


@pytest.mark.slow  # suite time (session 70: 15-260 s on 2 cores)
def test_nearby_lengths_share_the_fit_programs():
    (a,), model = _records((601,))
    sj.fit(model, a, max_steps=10)
    (b,), _ = _records((633,), seed=50)
    assert bucket_length(633) == bucket_length(601)
    with compiled_names() as names:
        res = sj.fit(model, b, max_steps=10)
    assert np.isfinite(res.loss)
    again = [n for n in names if any(p in n for p in FIT_PROGRAMS)]
    assert not again, f"another length in the same bucket compiled {again}"


def test_pad_records_and_the_causal_opt_out():
    from smafl_jax.identify._fit import _padded  # private: the padding rule itself (the fits above check its effect)

    (rec,), model = _records((601,))
    w = np.linspace(0.0, 1.0, 601)
    ((pu, py, pdt),), (pw,) = _padded(model, (rec,), (w,), True)
    n = bucket_length(601)
    assert pu.shape == py.shape == pw.shape == (n,) and pdt == rec[2]
    np.testing.assert_array_equal(pu[:601], rec[0])
    np.testing.assert_array_equal(pw[:601], w)
    assert np.all(pu[601:] == rec[0][-1]) and np.all(py[601:] == rec[1][-1]) and np.all(pw[601:] == 0.0)
    data, weights = _padded(model, (rec,), (w,), False)  # pad=False
    assert data[0] is rec and weights[0] is w

    class NotCausal(type(model)):  # a class whose outputs would see later inputs says so; its records stay as given
        causal = False

    other = NotCausal(thermal=model.thermal, hysteresis=model.hysteresis, sees=model.sees)
    data, weights = _padded(other, (rec,), (w,), True)
    assert data[0] is rec and weights[0] is w


class _Toy(eqx.Module):
    """y = a u, not finite where u > ``nan_above`` or from sample ``nan_from`` on (to provoke the padded fit's fallback)."""

    a: jnp.ndarray
    nan_above: float = eqx.field(static=True, default=np.inf)
    nan_from: int = eqx.field(static=True, default=10**9)

    def simulate(self, u, dt=None):
        bad = (u > self.nan_above) | (jnp.arange(u.shape[0]) >= self.nan_from)
        return self.a * u + jnp.where(bad, jnp.nan, 0.0)


def test_not_finite_outputs_are_named_and_padding_left_out():
    u = np.linspace(0.0, 1.0, 50)
    # not finite on the records as given: the same message (the sample of the records as given) with and without padding
    words = []
    for pad in (False, True):
        with pytest.raises(sj.UserInputError, match="not finite at the start") as err:
            sj.fit(_Toy(a=jnp.asarray(1.0), nan_above=0.7), (u, 2.0 * u), dt=1.0, init=None, pad=pad)
        words.append(str(err.value))
    assert words[0] == words[1]
    # not finite only on the padding (a model that is not finite beyond the record's length): the fit without it
    toy = _Toy(a=jnp.asarray(1.0), nan_from=50)
    r0, r1 = (sj.fit(toy, (u, 2.0 * u), dt=1.0, init=None, pad=p) for p in (False, True))
    assert float(r0.model.a) == pytest.approx(2.0) and float(r1.model.a) == float(r0.model.a) and r1.loss == r0.loss
