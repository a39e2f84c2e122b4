"""Residual diagnosis and effect attribution (issue 6).

Procedure (`diagnose`):

1. **Base model** (`choose_base`): a voltage input with dynamics gets the
   `Cascade` (Joule thermal lag + EUPI); a rate-free record (a ``branch``
   column, or a sample time >= 5 s: quasi-static data) or a non-voltage input
   (temperature, pressure) gets the `EUPI` on the input itself (``u_ref`` = input
   minimum for non-voltage inputs).
2. **Split** (`make_split`, rules in `smafl_jax.data.split`): with a ``branch`` column, the branches at
   positions ``2 mod 3`` of the sorted labels are held out (interleaved, so every held-out reversal lies between
   trained ones; branch 0, the major loop, is always trained on); otherwise the
   last 30 % of the record is held out (time block; the model is run over the
   whole record from the start and scored on the block).
3. **Residuals** of the base fit: whiteness (ACF with bounds, Ljung-Box),
   cross-correlation with the input's past, correlation with candidate signals
   (`smafl_jax.diagnosis._residuals`).
4. **Evidence** per catalogue effect: a score (Lagrange-multiplier) test.  The
   effect's signature is the change of the model output when the effect is
   switched on weakly (several probes cover its nuisance parameters); the
   base-model directions (EUPI features, thermal rate) are projected out, and
   the partial R^2 of the residual on the signature, with a Bartlett-effective
   sample size, gives the evidence.
5. **Attribution**: every applicable effect (with ``refine``, the default; else the plausible effects,
   p < 0.01, best first, up to 3; ``max_candidates`` / ``p_threshold`` set either), each fitted jointly with the base model (grid start
   for the effect's nonlinear parameters, linear least squares for the gains,
   then joint Levenberg-Marquardt).  Selection, ``rule="calibrated"`` (default,
   issue 13, `calibration_gates`): an effect is *accepted* when its held-out
   RMSE gain is >= ``min_gain`` (5 %), it does not raise the held-out max
   |error|, its gain is positive in all (or all but one) of 3 folds (contiguous
   time blocks each held out in turn, or the 3 branch residues), and the gain
   exceeds the (1 - fpr) quantile (fpr 1 %) of the gains the same effect reaches
   on 10 parametric-bootstrap null records (the fitted model without the effect
   plus an AR model of its own training residuals).  The best accepted one is
   selected; accepted ones within 10 % of its held-out RMSE are reported as an
   ambiguous set; a second effect must pass the same gates against the
   one-effect model.  Which effect is named is then decided on the whole record (``naming="whole"``,
   `smafl_jax.diagnosis._naming`): every fitted candidate refitted on every sample, the largest training-RMSE
   gain named (nothing below ``min_gain``), unless that whole-record base stays above 5x the noise (`WHOLE_BASE_MAX`), where the
   gates' choice stands.  ``rule="legacy"`` (issue 6): held-out gain >= ``min_gain``
   on one split and lower training BIC.  Nothing accepted: ``selected = []``
   and the strongest remaining residual correlate is reported.
6. **Base replacement** ``nonlocal_memory`` (rate-free records only: a
   ``branch`` column or dt >= 5 s): a discrete Preisach model
   (`smafl_jax.models._preisach`) replaces the EUPI; grid size and Tikhonov strength
   are chosen by inner cross-validation on the training segments only; it has
   no score test (it is not nested in the base), so it is always fitted there
   and competes under the same held-out RMSE + BIC rule, its parameter count
   being the effective degrees of freedom ``trace(H)``.  When it is selected no
   second effect is added (the catalogue effects act on the EUPI).
"""

from __future__ import annotations

import dataclasses
import time
from typing import TYPE_CHECKING

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import _config  # noqa: F401
from .._blas import blas_limited
from .._compile_cache import release_if_needed
from .._errors import UserInputError
from .._progress import LOGGER as PROGRESS
from .._progress import Steps
from ..effects import EFFECTS, ExtendedModel, Log, effect_rank
from ..identify._metrics import NOISE_FLOOR_WARN, metrics, noise_floor
from ..models._cascade import Cascade
from ..models._hysteresis import hysteresis_class, hysteresis_of, thermal_of
from ..models._padding import padded_call
from ..models._preisach import cv_fit_preisach
from ..models._thermal import JouleThermal
from ._residuals import candidate_signals, effective_n, signal_correlations, whiteness_report

if TYPE_CHECKING:
    from ._result import Diagnosis

__all__ = ["choose_base", "make_split", "fit_extended", "effect_evidence", "diagnose", "Segment", "Split"]

VOLTAGE_NAMES = ("voltage", "volt", "u_v")
LOAD_NAMES = ("load", "force", "mass", "weight")
RATE_FREE_DT = 5.0
HOLDOUT_FRACTION = 0.3


def _log(msg, verbose):
    """A progress line of `diagnose` (``verbose``): logged, and shown on stderr when logging is not configured."""
    from .._progress import say

    say(msg, verbose)


# -- base model and split ---------------------------------------------------------


def is_rate_free(record):
    return "branch" in record.extra or record.dt >= RATE_FREE_DT


def is_voltage(name):
    n = (name or "").lower()
    return any(k in n for k in VOLTAGE_NAMES) or n in ("u", "input")


def screened_base(base0, split, verbose=False):
    """``(base, table)``: ``base0`` with the orientation, hysteresis input and thermal start that `screen_start` picks.

    The residual -> effect loop is only as good as its base: a length sensor fitted with rising gains, or a
    cold-start record fitted from equilibrium, leaves structured residuals that some effect will "explain"
    (issues 13 and 18).  The training segments are screened; the held-out samples would choose the hysteresis input
    (`screen_start`'s fold score) only where one training and one held-out segment share a time axis (the interleaved
    split); the screening's training loss chooses on every split, as measured below.  ``table`` is None when the base has no hysteresis part to
    screen.

    Measured (session 51, `.notes/session51/base_probe.py`): screening a time-block split on the whole record's axis, the
    fold score choosing and the other input refined too as `smafl fit` does, moved the base's held-out error on 18
    records of experiments/indep_effects.py (12 clean) from a geometric mean of 2.22x to 2.37x the noise (better on 3,
    worse on 5, e.g. a clean PWM record 1.52x -> 7.27x), so the training loss stays.
    """
    from ..identify._choose import screen_start
    from ..models._hysteresis import hysteresis_of

    if hysteresis_of(base0) is None:
        return base0, None
    data = [(s.u, s.y, s.dt) for s in split.train]
    weights = [s.mask.astype(float) for s in split.train]
    # the training loss chooses, also on an interleaved split (held-out blocks on the training axis), as measured
    model, table, _ = screen_start(base0, data, weights, val_weights=None, memory="rule")
    th = getattr(model, "thermal", None)
    _log(
        f"base start screened: orientation {hysteresis_of(model).orientation:+d}"
        + (
            f", sees {model.sees}, thermal start {th.init}" + (f" u0 {float(th.u0):.4g}" if th.u0 is not None else "")
            if th
            else ""
        ),
        verbose,
    )
    return model, table


def _start_doc(model, screened):
    """How the base started (diagnosis.json ``base.start``): screened or fixed, orientation, thermal start."""
    from ..models._hysteresis import hysteresis_of

    h = hysteresis_of(model)
    th = getattr(getattr(model, "base", model), "thermal", None)
    doc = {"rule": "screened (as smafl fit)" if screened is not None else "fixed", "candidates": screened}
    if h is not None:
        doc["orientation"] = int(h.orientation)
    if th is not None:
        doc.update(thermal_init=th.init, u0=None if th.u0 is None else float(th.u0))
    return doc


def choose_base(record):
    """Untrained base model and the rule that picked it (see module docstring).

    Not `smafl fit`'s rule (`smafl_jax.identify._choose.auto_structure`): that one has no rate-free case (a
    quasi-static voltage record such as the FORC set gets a cascade there, the static hysteresis here) and tells
    voltages by other names and units, so sharing it would change diagnoses.  The hysteresis is the registry's
    ``"eupi"`` (`smafl fit --model eupi`; the catalogue effects act on its play thresholds).
    """
    h = hysteresis_class("eupi")
    u = np.asarray(record.u)
    u_min, u_max = float(u.min()), float(u.max())
    if is_voltage(record.input_name) and not is_rate_free(record):
        model = Cascade(thermal=JouleThermal(), hysteresis=h.from_range(0.0, u_max))
        return model, f"cascade: voltage input with dynamics (Joule thermal lag + {h.__name__} on the effective voltage)"
    if is_voltage(record.input_name):
        return h.from_range(u_min, u_max), f"{h.__name__} on the voltage: rate-free record (branch column or dt >= 5 s)"
    return (
        h.from_range(u_min, u_max, u_ref=u_min),
        f"{h.__name__} on the input: '{record.input_name}' is not a voltage (u_ref = input minimum)",
    )


def check_record(record):
    """Refuse records a diagnosis cannot identify anything from, with one line naming the file and column."""
    where = f"{record.path or record.name}"
    if record.y is None:
        raise UserInputError(f"{where}: diagnose needs an output column")
    u, y = np.asarray(record.u, float), np.asarray(record.y, float)
    for col, v in ((record.input_name, u), (record.output_name, y)):
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raise UserInputError(f"{where}: column '{col}' has a non-finite value at sample {int(bad[0])}")
    if np.ptp(u) == 0:
        raise UserInputError(
            f"{where}: input column '{record.input_name}' is constant ({u[0]:g}) over all {u.size} samples: "
            "a diagnosis needs an input that varies"
        )
    if np.ptp(y) == 0:
        raise UserInputError(f"{where}: output column '{record.output_name}' is constant ({y[0]:g}): nothing to fit")
    if is_voltage(record.input_name) and float(u.max()) <= 0:
        raise UserInputError(
            f"{where}: voltage column '{record.input_name}' is <= 0 everywhere (max {u.max():g} V); the actuator is "
            "driven by positive voltages (negate the column if the sign convention is inverted)"
        )


def _not_applicable_reason(name, base, rate_free, split):
    if name == NONLOCAL_MEMORY["name"]:
        return (
            "the Preisach replacement is offered for rate-free records only (a 'branch' column or a sample time >= "
            f"{RATE_FREE_DT:g} s); this record has dynamics (sample time {split.train[0].dt:g} s, no 'branch' column)"
        )
    cls = EFFECTS[name]
    if "thermal" in cls.needs and thermal_of(base) is None:
        return "it acts on the Joule thermal model, and this record's base model has none (not a voltage input with dynamics)"
    if "time" in cls.needs and rate_free:
        return "it needs time dynamics, and this record is rate-free"
    if "load" in cls.needs:
        return "it needs a load column (load, force, mass, weight) and a time split"
    return "not applicable"


def load_column(record):
    for k in record.extra:
        if any(n in k.lower() for n in LOAD_NAMES):
            return k
    return None


@dataclasses.dataclass
class Segment:
    """A stretch simulated from its start; scored on ``mask``."""

    time: np.ndarray
    u: np.ndarray
    y: np.ndarray
    dt: float
    mask: np.ndarray
    load: np.ndarray | None = None
    extra: dict = dataclasses.field(default_factory=dict)


@dataclasses.dataclass
class Split:
    kind: str
    rule: str
    train: list
    test: list
    train_labels: list = dataclasses.field(default_factory=list)
    test_labels: list = dataclasses.field(default_factory=list)


def _segment(rec, idx, mask=None, load_col=None):
    sub = rec.take(idx)
    n = len(sub)
    return Segment(
        time=sub.time,
        u=sub.u,
        y=sub.y,
        dt=rec.dt,
        # samples a resampling interpolated across a gap neither train nor score (`Record.measured`)
        mask=(np.ones(n, bool) if mask is None else np.asarray(mask, bool)) & sub.measured,
        load=None if load_col is None else sub.extra[load_col],
        extra={k: v for k, v in sub.extra.items() if k != "branch"},
    )


#: Rules of the diagnosis's split of a record without branches (`make_split`, `diagnose(split=...)`, CLI ``--split``).
DIAGNOSIS_SPLITS = ("auto", "time", "interleaved")


def _kind_of(split):
    """The `make_split` kind that gives ``split`` again on a record with the same input (null records)."""
    return split.kind if split.kind in DIAGNOSIS_SPLITS else "auto"


def make_split(record, holdout_fraction=HOLDOUT_FRACTION, holdout_residue=2, kind="time"):
    """Documented split (rules in `smafl_jax.data.split`): interleaved branches, the last 30 % as a time block, or
    interleaved time blocks.

    With a ``branch`` column: of the sorted branch labels, positions ``i % 3 == holdout_residue`` (default
    2) are held out, position 0 (the major loop) always trains (`data.split.branches`); other residues
    (0, 1) give the cross-validation folds of a branch record.  Otherwise ``kind``: ``"time"`` (default) the time block
    (`data.split.time_block`; the model is run from t = 0), ``"interleaved"`` every third of ten blocks
    (`data.split.interleaved`; the model runs through the whole record), ``"auto"`` the time block where the
    training part covers at least 90 % of the held-out part's input levels and directions, else interleaved
    (`data.split.make_split`'s rule).  Segments carry the record's load column.

    Why ``"auto"`` exists (issue 13, session 69): on the blind records of seeds 10-14 whose time block held out input
    the first 70 % had not visited (coverage < 60 %: triangles, ramps, staircases), the held-out gains measured
    extrapolation; the truth was named on 4 of 10 there against 20 of 30 elsewhere.  `diagnose` uses it by default
    since session 70, measured on every blind record of seeds 10-14 it moves and on clean records (docs/diagnosis.md,
    "Interleaved split"); this function keeps ``"time"`` as its own default.  The nulls of an interleaved split reach
    larger gains (a slow AR wander in the residual is interpolated between training blocks): the gates are stricter
    there on slow effects.
    """
    from ..data import split as _split

    if kind not in DIAGNOSIS_SPLITS:
        raise UserInputError(f"split must be one of {DIAGNOSIS_SPLITS}, got {kind!r}")
    branch = "branch" in record.extra
    if branch:
        if holdout_residue not in (0, 1, 2):
            raise UserInputError(f"holdout_residue must be 0, 1 or 2, got {holdout_residue!r}")
        sp = _split.branches(record, holdout_residue)
    else:
        sp = _split.make_split(record, kind, holdout_fraction=holdout_fraction)

    def labels(ls):  # numeric branch labels in diagnosis.json, as before (`data.split` labels are strings)
        return [int(float(k)) if float(k).is_integer() else float(k) for k in ls] if branch else list(ls)

    lc = load_column(record)
    train = [_segment(record, s.index, mask=s.mask, load_col=lc) for s in sp.train]
    test = [_segment(record, s.index, mask=s.mask, load_col=lc) for s in sp.test]
    return Split(sp.kind, sp.rule, train, test, labels(sp.train_labels), labels(sp.test_labels))


# -- simulation and metrics -------------------------------------------------------


@eqx.filter_jit
def _sim_jit(model, u, load, dt):
    # load=None is static here; models without a load input (Preisach) take (u, dt)
    return model.simulate(u, dt) if load is None else model.simulate(u, dt, load=load)


# The records' branches and blocks have many lengths: inputs are padded to a few lengths (`_padding`),
# so that they share compilations (causal models: the padded samples are dropped, the rest is unchanged).
def _sim(model, u, dt, load):
    return padded_call(_sim_jit, model, (u, load), dt)


_features_jit = eqx.filter_jit(lambda model, u, dt: model.features(u, dt))
_linear_columns_jit = eqx.filter_jit(lambda model, u, dt: model.linear_columns(u, dt))


def _features(model, u, dt):
    return padded_call(_features_jit, model, (u,), dt)


def _linear_columns(model, u, dt):
    return padded_call(_linear_columns_jit, model, (u,), dt)


def simulate_segment(model, seg):
    load = None if seg.load is None else jnp.asarray(seg.load)
    return np.asarray(_sim(model, jnp.asarray(seg.u), jnp.asarray(seg.dt), load))


def score(model, segs):
    y = np.concatenate([s.y[s.mask] for s in segs])
    yh = np.concatenate([simulate_segment(model, s)[s.mask] for s in segs])
    return metrics(y, yh), y - yh


# -- fitting ------------------------------------------------------------------------


def trainable_spec(model):
    """Train thermal k1, hysteresis weights and effect parameters; keep grids, k2 and load references fixed."""
    return model.trainable_spec()


def n_parameters(model):
    spec = trainable_spec(model)
    return int(sum(np.size(x) for x, t in zip(jax.tree_util.tree_leaves(model), jax.tree_util.tree_leaves(spec)) if t))


def _bvls(A, b, nonneg):
    """Bounded least squares (`smafl_jax.identify.linear.solve`: column-scaled, Cholesky-reduced BVLS).

    No ``drop_constant`` and no ``clip`` here, unlike `smafl_jax.identify._fit` (`varpro.DIAGNOSE_SOLVE` vs
    `varpro.FIT_SOLVE`): the diagnosis keeps its earlier numbers.
    """
    from ..identify.linear import solve
    from ..identify.varpro import DIAGNOSE_SOLVE

    return solve(A, b, nonneg, **DIAGNOSE_SOLVE).x


def _design(model, segs):
    """Stacked design matrix and targets over the scored samples, and the linear effect fields it adds.

    Columns: the hysteresis weights' features, the linear-stage effects' columns (`ExtendedModel.linear_columns`),
    then each output-stage effect's `profile_design` (the load effect scales them and adds its offset column).
    Returns ``(A, y, added)``, ``added`` the ``(effect name, field)`` of each column after the weights.
    """
    lin = model.linear_column_fields()
    outs = model.stage_effects("output")
    rows, targets = [], []
    added = list(lin)
    for s in segs:
        F = np.asarray(_features(model, jnp.asarray(s.u), jnp.asarray(s.dt)))[s.mask]
        if lin:  # linear effect fields enter beside the gains (before the output map, as in `ExtendedModel.simulate`)
            C = np.asarray(_linear_columns(model, jnp.asarray(s.u), jnp.asarray(s.dt)))[s.mask]
            for j in range(len(lin)):
                F = np.column_stack([F, C[:, j]])
        t = (np.arange(len(s.u)) * float(s.dt))[s.mask]
        load = None if s.load is None else np.asarray(s.load)[s.mask]
        added = list(lin)  # the same for every segment
        for e in outs:
            F, fields = e.profile_design(F, t, load)
            added += [(e.name, f) for f in fields]
        rows.append(F)
        targets.append(np.asarray(s.y, float)[s.mask])
    return np.concatenate(rows), np.concatenate(targets), added


def _compose_links(links):
    """One `OutputLink` for output maps applied in order (forward composed, inverse reversed, slope by the chain rule)."""
    if len(links) == 1:
        return links[0]

    def forward(z):
        for lk in links:
            z = lk.forward(z)
        return z

    def inverse(y):
        for lk in reversed(links):
            y = lk.inverse(y)
        return y

    def slope(z):
        d = 1.0
        for lk in links:
            d = d * lk.slope(z)
            z = lk.forward(z)
        return d

    return type(links[0])(forward, inverse, slope)


def profile_gains(model, segs, *, gn_steps=8):
    """Optimal hysteresis weights (bounded LS) for the model's nonlinear parameters; returns ``(model, sse)``.

    Variable projection: every model here is linear in the weights (and in the linear effect fields, such as
    the strain-accumulation rate and the load offset) except through a nonlinear output map (an output
    effect's `profile_link`, output saturation); then the weights start from the least-squares fit of the
    inverse-mapped output and are finished by Gauss-Newton steps, each a bounded least-squares problem.
    """
    eupi = model.hysteresis
    A, y, added = _design(model, segs)
    if not np.all(np.isfinite(A)):
        return model, np.inf
    nonneg = eupi.nonnegative_columns()
    for _ in added:  # linear effect fields are signed
        nonneg = np.r_[nonneg, False]
    links = [lk for lk in (e.profile_link() for e in model.stage_effects("output")) if lk is not None]
    if not links:
        theta = _bvls(A, y, nonneg)
        sse = float(np.sum((A @ theta - y) ** 2))
    else:
        link = _compose_links(links)
        smap = link.forward
        theta = _bvls(A, link.inverse(y), nonneg)
        sse = float(np.sum((smap(A @ theta) - y) ** 2))
        for _ in range(gn_steps):
            z = A @ theta
            J = A * link.slope(z)[:, None]
            cand = _bvls(J, y - smap(z) + J @ theta, nonneg)
            sse_c = float(np.sum((smap(A @ cand) - y) ** 2))
            if not sse_c < sse:
                break
            done = sse - sse_c < 1e-9 * sse
            theta, sse = cand, sse_c
            if done:
                break
    for name, field in reversed(added):
        model = eqx.tree_at(lambda mm: getattr(mm.get(name), field), model, jnp.asarray(theta[-1]))
        theta = theta[:-1]
    return model.with_hysteresis(eupi.with_linear_weights(jnp.asarray(theta))), sse


#: The thermal rate of a `Cascade` base: searched on a log scale like the effects' positive parameters.
_K1 = Log()
_K1_STEP = 0.5


def _phi_layout(model, ctx):
    """Nonlinear (profiled-over) parameters: ``(effect name or None for the thermal part, field, Transform, step)``.

    A thermal start given as an initial effective voltage ``u0`` (a screened base) is searched with k1: the two
    trade off (a cold start looks like a slow lag), so holding one while moving the other biases both.
    """
    lay = []
    if thermal_of(model) is not None:
        lay.append((None, "k1", _K1, _K1_STEP))
        th = model.base.thermal
        if th.init == "given" and th.u0 is not None:
            lay.append((None, "u0", _K1, _K1_STEP))
    for e in model.effects:
        lay += [(e.name, p.field, p.transform, p.step) for p in e.nonlinear(ctx)]
    return lay


def _get_phi(model, lay):
    out = []
    for name, field, tr, _ in lay:
        v = float(getattr(model.base.thermal, field)) if name is None else float(getattr(model.get(name), field))
        out.append(tr.to_phi(v))
    return np.array(out)


def _set_phi(model, lay, phi):
    for (name, field, tr, _), p in zip(lay, phi):
        v = jnp.asarray(tr.from_phi(p))
        if name is None:
            model = eqx.tree_at(lambda m: getattr(m.base.thermal, field), model, v)
        else:
            idx = [e.name for e in model.effects].index(name)
            model = eqx.tree_at(lambda m: getattr(m.effects[idx], field), model, v)
    return model


def _effect_class(name):
    if name not in EFFECTS:
        raise UserInputError(f"unknown effect {name!r}; catalogue: {list(EFFECTS)}")
    return EFFECTS[name]


def _effect_grid(name, ctx):
    """Starting points for an effect's nonlinear parameters (the gains come from least squares)."""
    return _effect_class(name).grid(ctx)


def _probe(name, ctx):
    """Weak versions of an effect whose output change is its residual signature."""
    return _effect_class(name).probes(ctx)


def applicable_effects(base, split, rate_free):
    """Catalogue effects that make sense for this base model and record."""
    out = []
    has_load = all(s.load is not None for s in split.train + split.test)
    for name, cls in EFFECTS.items():
        if "thermal" in cls.needs and thermal_of(base) is None:
            continue
        if "time" in cls.needs and rate_free:
            continue
        if "load" in cls.needs and (not has_load or len(split.train) != 1):
            continue
        out.append(name)
    return out


def _context(split):
    y = np.concatenate([s.y[s.mask] for s in split.train])
    ctx = {
        "dt": float(split.train[0].dt),
        "y_lo": float(y.min()),
        "y_range": float(np.ptp(y)) or 1.0,
        "y_mid": float(0.5 * (y.min() + y.max())),
    }
    ctx["duration"] = max(len(s.u) for s in split.train) * ctx["dt"]  # longest training stretch (creep tau bound)
    if split.train[0].load is not None:
        ld = np.concatenate([s.load for s in split.train])
        ctx["load_ref"] = float(np.mean(ld))
        ctx["load_scale"] = float(np.std(ld)) or 1.0
    return ctx


#: Nelder-Mead runs of `fit_extended`: from this many of the best grid starts, the lowest final loss kept
#: (`varpro.NelderMead.n_starts`), the runners-up only where the best start's simplex ends with a parameter at an end of
#: its range (`Transform.at_bound`: no interior minimum found there).  Refining the runners-up always (session 71,
#: docs/diagnosis.md "Session 71") gained creep s6011 of the independent plant (its best start ends at the tau bound;
#: from the third the simplex reaches the truth's sign and a lower training loss) but made clean s45 a false positive
#: and a diagnosis about 1.5x slower.  With the bound rule (session 72, "Session 72" there): creep s6011 named, the 10
#: clean records none, the other 9 records rerun unchanged.
REFINED_STARTS = 3


def fit_extended(base, effects, split, *, k1_grid=None, max_iter=None, verbose=False):
    """Fit ``ExtendedModel(base, effects)`` on the training segments jointly.

    Variable projection: the EUPI gains are profiled out by bounded least
    squares (`profile_gains`), and the few nonlinear parameters (thermal rate
    ``k1`` and the effects' parameters, log-transformed where positive) are
    searched by Nelder-Mead from the best of a small grid of starts (and its runners-up where that ends at a bound,
    `REFINED_STARTS`).  Effects
    already in ``base`` (an `ExtendedModel`) start from their fitted values.
    Returns ``(model, info)``.
    """
    from ..identify import varpro

    release_if_needed()  # every candidate structure compiles anew: stay under the process's memory-map limit
    ctx = _context(split)
    start = ExtendedModel.of(base)
    have = set(start.effect_names)
    new = [n for n in effects if n not in have]
    starts = []
    for combo in _product([_effect_grid(n, ctx) for n in new]):
        m = ExtendedModel(start.base, tuple(sorted(tuple(start.effects) + tuple(combo), key=lambda e: effect_rank(e.name))))
        starts.append(m)
    if k1_grid is not None and thermal_of(start) is not None:
        starts = [eqx.tree_at(lambda m: m.base.thermal.k1, c, jnp.asarray(k)) for c in starts for k in k1_grid]
    t0 = time.time()
    lay = _phi_layout(starts[0], ctx)  # every start has the same structure, so the same layout

    def project(phi, best):
        m, sse = profile_gains(_set_phi(best, lay, phi), split.train)
        return varpro.Profiled(sse, m)

    # Nelder-Mead from the best start: one simplex step per parameter (its transform's scale), the loss memoised on
    # the point rounded to 12 decimals (the simplex revisits points), a non-finite loss counted as 1e300
    nm = varpro.NelderMead(
        steps=[step for *_, step in lay],
        maxiter=max_iter or 150 * len(lay),
        xatol=1e-4,
        fatol=1e-10,
        cache_decimals=12,
        bad=1e300,
        n_starts=REFINED_STARTS,
        retry_if=lambda phi: any(tr.at_bound(p) for (_, _, tr, _), p in zip(lay, phi)),
    )
    res = varpro.search(
        project,
        starts,
        x_of=lambda m: _get_phi(m, lay),
        score=lambda m: profile_gains(m, split.train)[1],
        refine=nm if lay else None,
        none_finite="every starting point of the fit gave a non-finite output",
    )
    model, sse = res.profiled.model, res.profiled.loss
    n_eval = len(starts) + res.n_evals
    converged = res.converged
    info = {
        "n_starts": len(starts),
        "n_evaluations": n_eval,
        "refined_runs": res.n_runs,
        "nonlinear_parameters": len(lay),
        "converged": converged,
        "train_sse": sse,
        "seconds": time.time() - t0,
    }
    runs = f", {res.n_runs} simplex runs (best start at a bound)" if res.n_runs > 1 else ""
    _log(
        f"  fit {'+'.join(effects) or 'base'}: {len(starts)} starts, {n_eval} evaluations{runs}, {info['seconds']:.1f} s", verbose
    )
    return model, info


#: LM steps of the symmetric refinement (`refine_model`): the real record's base and candidates, and on null records.
REFINE_MAX_STEPS = 200
NULL_REFINE_MAX_STEPS = 60


def _refine_spec(model):
    """Trainable spec of the symmetric refinement: the model's own rule plus every optional hysteresis group
    (`AbstractHysteresis.trainable_groups`: an EUPI's thresholds and tilts), and a fitted operator memory."""
    from ..identify._fit import default_trainable
    from ..models._hysteresis import hysteresis_of

    spec = default_trainable(model)
    h = hysteresis_of(model)
    groups = tuple(getattr(h, "trainable_groups", {}))
    free = [f for f in h.fixed_fields() if f not in h.fixed_fields(groups)]
    if not free:
        return spec
    return eqx.tree_at(lambda s: [getattr(hysteresis_of(s), f) for f in free], spec, [True] * len(free))


def refine_model(model, split, *, max_steps=REFINE_MAX_STEPS):
    """Joint LM refinement of a fitted model on the training samples (gains, thermal rate, effect parameters,
    thresholds, tilts, fitted operator memory); the model itself when there is nothing to refine or the
    refinement does not lower the training loss or raises the held-out error (the gate `smafl fit` applies).

    Applied with the SAME freedom to the base and to every candidate effect model (and on the null records to
    both), so that they compete on equal terms: a base refined alone absorbs part of an effect that a
    candidate left at its variable-projection fit cannot take back (session 8), and a candidate refined alone
    would win on freedom, not on physics.  Records with a load column are left as fitted (`fit` has no load input).
    """
    from ..identify._fit import fit
    from ..models._hysteresis import hysteresis_of

    if hysteresis_of(model) is None or any(s.load is not None for s in split.train):
        return model
    data = [(s.u, s.y, s.dt) for s in split.train]
    weights = [s.mask.astype(float) for s in split.train]
    res = fit(model, data, trainable=_refine_spec(model), init=None, weights=weights, max_steps=max_steps)
    if not (np.isfinite(res.loss) and res.loss <= res.init_loss):
        return model
    # As `smafl fit` gates its joint refinement: kept only if it does not raise the held-out error (thresholds and tilts
    # can buy training error with shapes that do not carry; an own-generator strain record: held-out 0.0046 -> 0.013)
    before, after = _held(model, split)["rmse"], _held(res.model, split)["rmse"]
    return res.model if np.isfinite(after) and after <= before else model


def n_refined_parameters(model):
    """Free parameters under the symmetric refinement (`_refine_spec`): the base's own, thresholds and tilts, and a
    fitted operator memory; what the training BIC of `refined_base` counts."""
    spec = _refine_spec(model)
    return int(sum(np.size(x) for x, t in zip(jax.tree_util.tree_leaves(model), jax.tree_util.tree_leaves(spec)) if t))


def refined_base(base, start, split, verbose=False):
    """``(model, start, doc)``: the variable-projection base refined (`refine_model`) and its profiled start (where
    the candidate effects start from, to be refined with the same freedom), the operator memory at t = 0 by rule
    and, on a single training segment, fitted (`fitted_memory_start` from the screened ``start``), and for a cascade
    the drive's sampling convention (`JouleThermal.lag` 0 or 1 sample), chosen on the held-out samples as `smafl fit`
    chooses its memory on the validation block. Each variant's training SSE, parameter count and BIC are in the doc.

    Why: on clean records of an independent plant the rule memory leaves the base at 10x the noise on held-out data
    (the plant starts on a branch the rule does not know), and a plant whose drive acts from the next sample leaves a
    one-sample timing error on PWM and step drives; every effect (above all "delay") then "explains" that misfit.
    With both chosen, the same base reaches about 1x (experiments/oracle_attribution.py).
    """
    import dataclasses

    from ..identify._choose import fitted_memory_start

    variants = [(0, start, base)]
    th = thermal_of(start)
    if th is not None and hasattr(th, "lag") and hasattr(start, "thermal"):
        other = 1 - th.lag
        _log(
            f"  base refinement: the base with a drive lag of {other} sample(s), then each lag with rule and fitted memory",
            verbose,
        )
        s1 = dataclasses.replace(start, thermal=dataclasses.replace(th, lag=other))
        variants.append((other, s1, fit_extended(s1, [], split)[0]))
    runs = []
    t0 = time.time()
    n_runs = len(variants) * (2 if len(split.train) == 1 else 1)  # at most: a fitted memory may not be found
    # a minute or more each on long records: one line per variant, so the phase is never silent for minutes
    done = lambda label: _log(f"  base refinement: {label} done ({len(runs)}/{n_runs}, {time.time() - t0:.0f} s)", verbose)
    for lag, st, b in variants:
        tag = f"lag {lag}, " if th is not None else ""
        runs.append((tag + "rule", refine_model(b, split), b))
        done(tag + "rule memory")
        if len(split.train) == 1:
            s = split.train[0]
            fm = fitted_memory_start(st, [(s.u, s.y, s.dt)], [s.mask.astype(float)])
            if fm is not None:
                b = fit_extended(fm[0], [], split)[0]
                runs.append((tag + "fitted", refine_model(b, split), b))
                done(tag + "fitted memory")
    held = {label: _held(m, split)["rmse"] for label, m, _ in runs}
    # Chosen on the held-out block although that block then judges the candidates (a bias: the base's figure is the
    # least of 4). The training BIC was tried instead (session 42, .notes/session42/probe_base.py): on 60 independent
    # records it picked another variant on 36, held out > 20 % worse on 18 of them and up to 13x (a fitted memory
    # buying training error with gains that do not carry); on the 11 clean records where the two differ the held-out
    # pick is better by a median 1.2 %: the bias is that small, the harm of the training choice is not.
    ic = {label: information_criteria(m, split.train, k=n_refined_parameters(m)) for label, m, _ in runs}
    label, model, profiled = min(runs, key=lambda r: held[r[0]] if np.isfinite(held[r[0]]) else np.inf)
    _log(
        "base refinement: "
        + ", ".join(f"{k} (train BIC {ic[k]['bic']:.6g}, held-out RMSE {held[k]:.4g})" for k in held)
        + f" -> {label}",
        verbose,
    )
    doc = {
        "chosen": label,
        "heldout_rmse": held,
        "train": {k: {"sse": v["sse"], "k": v["k"], "bic": v["bic"]} for k, v in ic.items()},
        "refined": "gains, thermal rate, optional hysteresis groups (thresholds, tilts), operator memory",
        "rule": "operator memory (rule / fitted) and drive sampling lag (0 / 1 sample) chosen on the held-out samples",
    }
    return model, profiled, doc


#: Passes of `converged_base` at most, and the relative training-SSE gain below which a pass has converged.
BASE_PASSES, BASE_PASS_RTOL = 3, 1e-3


def converged_base(base, split, verbose=False):
    """``(model, passes)``: the refined base passed again through a candidate's procedure without an effect (variable
    projection of the gains with the thermal rate searched, then `refine_model`) until a pass lowers the training SSE
    by less than ``BASE_PASS_RTOL`` (at most ``BASE_PASSES`` passes); a pass that raises the held-out error is not kept.

    Why: a candidate fitted from the refined base gets one such pass more than the base; on a clean independent record
    every one of 13 candidates then held out 7-34 % better than the base (sensor_lead selected), a gain of the extra
    pass, not of any effect. With the base converged, a candidate's gain is its effect's."""
    passes = []
    sse, held = _train_sse(base, split.train), _held(base, split)["rmse"]
    for _ in range(BASE_PASSES):
        m = refine_model(fit_extended(base, [], split)[0], split)
        new, held_new = _train_sse(m, split.train), _held(m, split)["rmse"]
        passes.append({"train_sse_before": sse, "train_sse_after": new, "heldout_rmse_after": held_new})
        # kept as `refine_model` keeps a refinement: lower training loss without a higher held-out error
        if not (np.isfinite(new) and new < sse and held_new <= held):
            break
        held = held_new
        base, gain, sse = m, (sse - new) / sse, new
        if gain < BASE_PASS_RTOL:
            break
    _log("base passes: " + ", ".join(f"{p['train_sse_before']:.4g} -> {p['train_sse_after']:.4g}" for p in passes), verbose)
    return base, passes


def _from_refined_base_too(m, info, base, cand_start, name, split, verbose=False):
    """The candidate ``name`` fitted from the refined base as well, keeping the lower TRAINING loss of the two fits.

    Why: the candidate nests the base (effect strength 0), yet from the profiled start alone its refinement can end
    above the refined base in training (rejected by the held-out gate, or a poorer local minimum): an independent
    rate-dependence record, base 1.17x the noise in training, its candidate 1.34x. The choice is made on training
    data only; the null records' candidates start from the refined base already (`calibration_gates`)."""
    if base is cand_start:
        return m, info
    m2, info2 = fit_extended(base, [name], split, verbose=verbose)
    m2 = refine_model(m2, split)
    sse1, sse2 = _train_sse(m, split.train), _train_sse(m2, split.train)
    info = {**info, "start": "profiled base", "train_sse_from_profiled_base": sse1, "train_sse_from_refined_base": sse2}
    if np.isfinite(sse2) and not sse2 >= sse1:
        return m2, {**info2, **{k: v for k, v in info.items() if k != "start"}, "start": "refined base"}
    return m, info


def _product(lists):
    out = [()]
    for lst in lists:
        out = [o + (x,) for o in out for x in lst]
    return out


def _train_sse(model, segs):
    return float(sum(np.sum((simulate_segment(model, s) - s.y)[s.mask] ** 2) for s in segs))


#: Catalogue entry of the Preisach base replacement (see module docstring, step 6).
NONLOCAL_MEMORY = {
    "name": "nonlocal_memory",
    "physics": (
        "Return-point (wiping-out) memory without congruency: the SMA's phase-fraction hysteresis is a Preisach-type "
        "distribution of hysterons (relays switching up at a, down at b <= a); first-order reversal curves identify "
        "it, and play-operator (PI/EUPI) models cannot represent its non-congruent minor loops. Offered for "
        "rate-free records only."
    ),
    "parameters": {
        "w_ab": "hysteron weights on the triangular level grid (>= 0)",
        "n_levels, lam": "grid size and Tikhonov strength, chosen by inner CV on the training segments",
    },
}


def information_criteria(model, segs, k=None):
    n = int(sum(s.mask.sum() for s in segs))
    sse = _train_sse(model, segs)
    if k is None:
        k = n_parameters(model)
    ll = n * np.log(max(sse, 1e-300) / n)
    return {"n": n, "sse": sse, "k": k, "aic": float(ll + 2 * k), "bic": float(ll + k * np.log(n))}


# -- evidence ----------------------------------------------------------------------


def _project_out(B, x):
    coef, *_ = np.linalg.lstsq(B, x, rcond=None)
    return x - B @ coef


def effect_evidence(model, split, names, residual):
    """Score-test evidence for each effect name: partial R^2 of the training residual on its signature."""
    ctx = _context(split)
    seg_y = [simulate_segment(model, s) for s in split.train]
    base_cols = [np.asarray(_features(model, jnp.asarray(s.u), jnp.asarray(s.dt)))[s.mask] for s in split.train]
    B = np.concatenate(base_cols)
    if thermal_of(model) is not None:
        k1 = model.base.thermal.k1
        pert = eqx.tree_at(lambda m: m.base.thermal.k1, model, k1 * 1.01)
        dk = np.concatenate([(simulate_segment(pert, s) - y0)[s.mask] for s, y0 in zip(split.train, seg_y)])
        B = np.column_stack([B, dk])
    colscale = np.maximum(np.sqrt(np.mean(B**2, axis=0)), 1e-12)
    B = B / colscale
    e = _project_out(B, residual)
    out = {}
    for name in names:
        best = None
        for probe in _probe(name, ctx):
            m = ExtendedModel(model.base, tuple(model.effects) + (probe,))
            sig = np.concatenate([(simulate_segment(m, s) - y0)[s.mask] for s, y0 in zip(split.train, seg_y)])
            sp = _project_out(B, sig)
            if not np.all(np.isfinite(sp)) or np.std(sp) < 1e-12 * (np.std(sig) + 1e-300):
                continue
            r = float(np.corrcoef(e, sp)[0, 1]) if np.std(e) > 0 else 0.0
            n_eff = effective_n(e, sp)
            stat = n_eff * r * r
            from scipy import stats

            item = {
                "partial_r2": r * r,
                "corr": r,
                "n_eff": n_eff,
                "lm_stat": stat,
                "p_value": float(stats.chi2.sf(stat, 1)),
                "probe": {k: float(np.asarray(getattr(probe, k))) for k in probe.parameters if hasattr(probe, k)},
            }
            if best is None or item["partial_r2"] > best["partial_r2"]:
                best = item
        out[name] = best or {"partial_r2": 0.0, "corr": 0.0, "n_eff": 0.0, "lm_stat": 0.0, "p_value": 1.0, "probe": {}}
    return out


# -- calibrated selection (issue 13) ------------------------------------------------------

#: Defaults of the calibrated rule (see `diagnose`).  ``n_null`` is kept small on purpose (each null record costs
#: a base refit and an effect fit); the (1 - fpr) quantile of so few null gains is estimated with a normal
#: approximation and, in addition, the gain must exceed every null gain (an empirical rank p <= 1 / (n_null + 1)).
#: Score-test screening without the refinement (``refine=False``): the plausible effects (p < 0.01), best 3.
LEGACY_SCREEN = {"p_threshold": 0.01, "max_candidates": 3}
CALIBRATED_DEFAULTS = {"fpr": 0.01, "n_null": 10, "n_folds": 3, "ar_max_order": 20, "ambiguity": 0.10}
SELECTION_RULES = ("calibrated", "legacy")
NAMING_RULES = ("whole", "split")
#: A base model whose held-out RMSE is at most this many output-noise SDs (`noise_floor`, estimated from the record's
#: sample-to-sample scatter) is at the noise floor, issue 13's own definition ("within 1.2x the noise standard
#: deviation"): the calibrated rule then tests no effect.  Why: what is left is noise, and an effect that lowers it
#: fits noise (independent plant A, clean PWM cold record seed 12, session 52: base 1.19x, creep selected at 1.13x); an
#: effect the issue asks to find changes the output by >= 5x the noise and must cut the held-out RMSE by >= 50 %,
#: which a base at 1.2x cannot show.  It also skips the folds and null records, the diagnosis's longest part.
BASE_AT_FLOOR = 1.2

#: Structure the base leaves on its training samples, in output-noise SDs (`structure_left_sd`), below which a
#: diagnosis that names nothing says so: what an effect changes there, the base's own freedom (thermal rate, start
#: state, polynomial, operator gains) has mimicked, so "none" means none detectable, not none present.  Measured
#: blind (session 73, independent plant, seeds 10-14): the truth was named on 22 of 25 effect records where the base
#: left >= 1 SD and on 5 of 15 below, most of them with the truth's whole-record gain under 5 %.
DETECTABLE_STRUCTURE_SD = 1.0


def structure_left_sd(train_ratio):
    """RMS of the base's training misfit above the noise, in noise SDs: ``sqrt(max(r^2 - 1, 0))`` for a training RMSE
    of ``r`` noise SDs (independent noise adds in quadrature); None when ``r`` is unknown."""
    if train_ratio is None or not np.isfinite(train_ratio):
        return None
    return float(np.sqrt(max(train_ratio * train_ratio - 1.0, 0.0)))


#: Held-out over training RMSE of the base above which `diagnose` warns that its held-out block measures how the base
#: generalises rather than missing physics.  Measured blind on 114 independent records (sessions 30-63,
#: experiments/results/diagnose_independent_session63/README.md): with a gap of 4x or more a selection named the true effect
#: on 4 of 12 (5 wrong effects, 3 on clean or uncatalogued records), with a gap below 2x on 19 of 27.
GENERALISATION_GAP_WARN = 4.0


def generalisation_warning(train_rmse: float, heldout_rmse: float) -> str | None:
    """The warning of a base that holds out at `GENERALISATION_GAP_WARN` x its training RMSE or more, else None."""
    if not (train_rmse > 0 and np.isfinite(heldout_rmse)) or heldout_rmse < GENERALISATION_GAP_WARN * train_rmse:
        return None
    return (
        f"the base model holds out at {heldout_rmse / train_rmse:.3g}x its training RMSE: the held-out gains that decide the "
        "selection measure how the base carries to that block (an untrained branch, a start it cannot pin down) more than "
        "a missing effect; on independent records with such a gap a selection named the true effect 4 times in 12 "
        "(19 in 27 with a gap below 2x), and 'none' is no evidence of a clean record either"
    )


def _at_noise_floor(base_h, noise_sd):
    """The base's held-out RMSE over the noise SD when it is within `BASE_AT_FLOOR`, else None (no estimate: None)."""
    ratio = base_h / noise_sd if noise_sd else None
    return ratio if ratio is not None and ratio <= BASE_AT_FLOOR else None


def _segment_index(record):
    """Record indices of the segments of `whole_record_split` (one per branch, or the whole record)."""
    if "branch" in record.extra:
        b = np.asarray(record.extra["branch"]).astype(int)
        return [np.flatnonzero(b == k) for k in dict.fromkeys(b.tolist())]
    return [np.arange(len(record))]


#: Equal blocks of the interleaved folds (`fold_splits(kind="interleaved")`), as the interleaved split's.
INTERLEAVED_BLOCKS = 10


def fold_splits(record, n_folds=3, kind="time"):
    """Cross-validation folds, each a `Split`: K contiguous time blocks, each held out in turn (the model runs
    from t = 0 over the whole record, the other blocks train), or for a branch record the three branch residues.

    ``kind="interleaved"`` (the main split interleaved, `make_split`): fold j holds out every K-th of
    `INTERLEAVED_BLOCKS` equal blocks from block j (the first block, the initial state, always trains), so that no
    fold holds out what the main split avoided, a stretch of input levels its training part never visits."""
    if "branch" in record.extra:
        out = []
        for r in (0, 1, 2):
            try:
                out.append(make_split(record, holdout_residue=r))
            except UserInputError:  # too few branches for this residue
                continue
        return out
    n = len(record)
    if n_folds < 2 or n < 20 * n_folds:
        raise UserInputError(f"{n_folds} folds need at least {20 * n_folds} samples (and n_folds >= 2); the record has {n}")
    lc = load_column(record)
    edges = np.linspace(0, n, n_folds + 1).round().astype(int)
    full = np.arange(n)
    blocks = np.array_split(full, max(INTERLEAVED_BLOCKS, n_folds + 1))
    out = []
    for j in range(n_folds):
        if kind == "interleaved":
            chosen = [b for b in range(len(blocks)) if b % n_folds == j and b != 0]
            held = np.isin(full, np.concatenate([blocks[b] for b in chosen]))
            label = "blocks " + ",".join(str(b) for b in chosen)
        else:
            held = (full >= edges[j]) & (full < edges[j + 1])
            label = f"{edges[j]}..{edges[j + 1] - 1}"
        out.append(
            Split(
                "time-fold",
                f"block {label} held out, the rest trained (model run from t = 0)",
                [_segment(record, full, mask=~held, load_col=lc)],
                [_segment(record, full, mask=held, load_col=lc)],
                [f"all but {label}"],
                [label],
            )
        )
    return out


def _ar_fit(e, max_order):
    """AR(p) model of a residual series, p <= ``max_order`` chosen by BIC on a common sample; made stable.

    Returns ``(coef, innovations, mean, spectral_radius)``; coefficients whose characteristic roots reach
    the unit circle are shrunk (a_i -> a_i s^i) to radius 0.995, so that simulated nulls stay stationary.
    """
    e = np.asarray(e, float)
    mu = float(e.mean())
    x = e - mu
    n = x.size
    pmax = int(min(max_order, max(n // 10, 0)))
    y0 = x[pmax:]
    best = (len(y0) * np.log(max(float(np.mean(y0**2)), 1e-300)), np.zeros(0), y0)
    for p in range(1, pmax + 1):
        X = np.column_stack([x[pmax - i : n - i] for i in range(1, p + 1)])
        coef, *_ = np.linalg.lstsq(X, y0, rcond=None)
        innov = y0 - X @ coef
        bic = len(y0) * np.log(max(float(np.mean(innov**2)), 1e-300)) + p * np.log(len(y0))
        if bic < best[0]:
            best = (bic, coef, innov)
    _, coef, innov = best
    rho = float(np.max(np.abs(np.roots(np.r_[1.0, -coef])))) if coef.size else 0.0
    if rho >= 0.995:
        coef = coef * (0.995 / rho) ** np.arange(1, coef.size + 1)
        rho = 0.995
    return coef, innov - innov.mean(), mu, rho


def _ar_simulate(coef, innov, mu, rho, n, rng):
    """One AR path of length ``n`` driven by innovations resampled (with replacement) from the fitted ones."""
    from scipy.signal import lfilter

    burn = int(min(20000, max(200, 10 * coef.size, 5.0 / max(1.0 - rho, 1e-3))))
    eta = rng.choice(innov, size=n + burn, replace=True)
    return mu + lfilter([1.0], np.r_[1.0, -coef], eta)[burn:]


def null_records(record, split, model, n_null, rng, max_order=20):
    """Parametric-bootstrap null records: ``model`` (fitted on the training split) simulated over the whole record
    plus an AR(p) path fitted to its own training residuals (innovations resampled).  Returns ``(records, info)``."""
    _, res_tr = score(model, split.train)
    coef, innov, mu, rho = _ar_fit(res_tr, max_order)
    full = whole_record_split(record)
    yhat = np.empty(len(record))
    for idx, seg in zip(_segment_index(record), full.train):
        yhat[idx] = simulate_segment(model, seg)
    recs = []
    for _ in range(n_null):
        ystar = yhat.copy()
        for idx in _segment_index(record):
            ystar[idx] += _ar_simulate(coef, innov, mu, rho, idx.size, rng)
        recs.append(dataclasses.replace(record, y=ystar))
    info = {
        "residual_model": f"AR({coef.size}) fitted to the training residuals (BIC, order <= {max_order}), innovations resampled",
        "ar_order": int(coef.size),
        "ar_spectral_radius": rho,
        "innovation_sd": float(np.std(innov)) if innov.size else 0.0,
        "residual_sd": float(np.std(res_tr)),
    }
    return recs, info


#: Nelder-Mead evaluations per nonlinear parameter when an effect is refitted on a null record (the real fit: 150).
NULL_MAX_ITER_PER_PARAMETER = 30


def _fit_on(name, start, split, record, *, new, refine=False):
    """Refit on another split (folds, null records).

    ``new=False``: the linear EUPI gains (and linear effect gains) are re-profiled by bounded least squares with
    the nonlinear parameters (k1, effect parameters) kept at their fitted values: one solve, cheap.
    ``new=True``: ``start`` (a fitted model without ``name``) plus effect ``name`` from its grid of starts and a
    Nelder-Mead search capped at ``NULL_MAX_ITER_PER_PARAMETER`` evaluations per parameter (the real fit's
    procedure, shortened for speed).  ``refine``: then refined as the real record's models were (`refine_model`,
    fewer steps), so that the null gains are those of the same procedure.  ``nonlocal_memory``: the Preisach fit
    with its inner CV.
    """
    if name == NONLOCAL_MEMORY["name"]:
        u = np.asarray(record.u, float)
        return cv_fit_preisach(split.train, float(u.min()), float(u.max()), progress=False)[0]
    if hysteresis_of(start) is start:  # a bare hysteresis model: the nonlocal-memory replacement keeps its CV fit
        return start
    if new:
        have = list(ExtendedModel.of(start).effect_names)
        n_par = len(EFFECTS[name].nonlinear(_context(split))) + len(have) + (1 if thermal_of(start) is not None else 0)
        m = fit_extended(start, have + [name], split, max_iter=NULL_MAX_ITER_PER_PARAMETER * max(n_par, 1))[0]
    else:
        m = profile_gains(start, split.train)[0]
    return refine_model(m, split, max_steps=NULL_REFINE_MAX_STEPS) if refine else m


def _held(model, split):
    te, _ = score(model, split.test)
    return te


#: Floor of a fold's gain in the mean-fold clause: a fold whose held-out error more than doubles has diverged (its
#: re-profiled gains blow up on a block the other blocks never excited) and counts as a doubling, so that one such
#: fold cannot outweigh the others by its size alone. Measured on the 141 stored fold tests (`.notes/session30/
#: fold_rule.py`): the floor admits the output_lag record of seed 1 (fold gains -57.7, +0.72, +0.46) and no wrong name.
FOLD_GAIN_FLOOR = -1.0


def folds_gate(gains, min_mean: float = 0.0, determined=None) -> tuple[bool, float]:
    """``(passed, mean)``: the gain is positive in all folds or all but one, and the folds together show the gain asked
    of the main split (the mean of the gains, each floored at `FOLD_GAIN_FLOOR`, at least ``min_mean``; the diagnosis
    passes its ``min_gain``, 5 %).

    ``determined`` (one bool per fold, `fold_undetermined`): when some folds are undetermined and at least two are
    not, only the determined folds count, and each of them must show a gain (an undetermined fold says nothing either
    way, so it cannot be the one allowed exception either).

    Why the mean must reach ``min_gain`` and not just 0 (session 31): on clean independent records a timing effect with
    a 6-12 % gain on the main split and fold gains like -0.13 / +0.08 / +0.13 (mean +2.7 %) passed; over the 177 stored
    blind diagnoses, fold means of 2-4 % were three clean records' false selections, one wrong name and one true name
    (resistance_tc seed 3, ambiguous with nonlinear_cooling, 7 % on the split, 3.4 % over the folds)."""
    gains = [float(g) for g in gains]
    allowed = 1
    if determined is not None and 2 <= sum(map(bool, determined)) < len(gains):
        gains, allowed = [g for g, d in zip(gains, determined) if d], 0
    if not gains:
        return False, 0.0
    mean = float(np.mean(np.maximum(gains, FOLD_GAIN_FLOOR)))
    n_pos = sum(g > 0 for g in gains)
    return bool(len(gains) >= 2 and n_pos >= len(gains) - allowed and mean > 0 and mean >= min_mean), mean


#: A fold is *undetermined* when the part of a re-profiled model's held-out prediction that lies in directions of the
#: gains the fold's training samples leave undetermined (singular values of the column-scaled training design below
#: `FOLD_RCOND` of the largest) has an RMS above this multiple of that model's training RMSE on the fold: the fold's
#: verdict is then set by an arbitrary choice of the solver, not by the data.
FOLD_UNDETERMINED = 1.0
FOLD_RCOND = 1e-9


def fold_undetermined(model, fs) -> float:
    """RMS of ``model``'s held-out prediction on fold ``fs`` that its training samples do not determine, over its
    training RMSE (0 for models without profiled gains).  Uses the fold's inputs only, never its held-out output.

    Why (session 64): a creep record (effect 15x the noise) was rejected by one fold whose training blocks, after the cold
    start, never moved the play operators that the held-out first block moved (their columns nearly constant there,
    condition number 1e16); the bounded least squares chose their gains arbitrarily and the candidate held out 18x
    worse than the base.  Re-profiled with a ridge the sign of that fold flipped with the ridge strength."""
    if hysteresis_of(model) is model or not hasattr(model, "linear_column_fields"):
        return 0.0
    A, _, added = _design(model, fs.train)
    At, _, _ = _design(model, fs.test)
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(At))) or A.shape[0] == 0 or At.shape[0] == 0:
        return 0.0
    theta = np.asarray(model.hysteresis.linear_weights(), float)
    for name, field in added:
        theta = np.r_[theta, float(getattr(model.get(name), field))]
    scale = np.sqrt(np.sum(A**2, axis=0))
    scale[scale == 0] = 1.0
    _, sv, vt = np.linalg.svd(A / scale, full_matrices=False)
    v0 = vt[sv < FOLD_RCOND * sv[0]]
    if len(v0) == 0:
        return 0.0
    p0 = (At / scale) @ (v0.T @ (v0 @ (scale * theta)))
    return float(np.sqrt(np.mean(p0**2)) / max(score(model, fs.train)[0]["rmse"], 1e-300))


def calibration_gates(
    record,
    split,
    current,
    current_te,
    name,
    cand,
    cand_te,
    *,
    min_gain,
    fpr,
    n_null,
    n_folds,
    holdout_residue,
    rng,
    fold_cache,
    max_order=20,
    refine=False,
    verbose=False,
):
    """The calibrated acceptance test of candidate ``name`` (fitted model ``cand``) against ``current``.

    Gates, cheapest first (a failing gate stops the test):

    1. ``gain``: held-out RMSE gain on the main split >= ``min_gain``;
    2. ``max_error``: held-out max |error| (the numerator of e_r) not raised;
    3. ``folds``: on each of K contiguous blocks held out in turn (branch records: the three branch residues),
       both models refitted (linear gains re-profiled), the gain is positive in all folds or all but one, and the
       mean fold gain (each fold's gain floored at ``FOLD_GAIN_FLOOR``) is at least ``min_gain`` (`folds_gate`);
    4. ``null``: the gain exceeds the (1 - fpr) quantile of the gains the same effect reaches on ``n_null``
       null records simulated from ``current`` with its own residual structure (`null_records`), each refitted
       exactly like the real record (current: warm start; effect: its grid of starts); the quantile is a normal
       approximation (mean + z sd of the null gains clipped at 0: one-sided) and the gain must also exceed every
       null gain.

    Returns a JSON-ready dict: gates, per-fold gains, the null distribution and its threshold, ``accepted``.
    """
    from scipy import stats

    base_h, base_max = current_te["rmse"], current_te["max_abs_error"]
    gain = 1.0 - cand_te["rmse"] / base_h if base_h > 0 else 0.0
    out = {"gain": gain, "gates": {}, "accepted": False}
    out["gates"]["gain"] = bool(gain >= min_gain)
    if not out["gates"]["gain"]:
        out["reason"] = f"held-out gain {100 * gain:.1f} % < {100 * min_gain:.0f} %"
        return out
    out["heldout_max_abs_error"] = {"before": base_max, "after": cand_te["max_abs_error"]}
    out["gates"]["max_error"] = bool(cand_te["max_abs_error"] <= base_max)
    if not out["gates"]["max_error"]:
        out["reason"] = f"raises the held-out max |error| ({base_max:.4g} -> {cand_te['max_abs_error']:.4g})"
        return out
    t0 = time.time()
    folds = []
    splits = fold_cache.setdefault("splits", fold_splits(record, n_folds, kind=split.kind))
    steps = Steps(f"{name}: fold test", len(splits), unit="folds")
    for j, fs in enumerate(splits):
        key = (id(current), j)
        if key not in fold_cache:
            cm = _fit_on(None, current, fs, record, new=False)
            fold_cache[key] = (_held(cm, fs), fold_undetermined(cm, fs))
        b, und_b = fold_cache[key]
        cm = _fit_on(name, cand, fs, record, new=False)
        c, und_c = _held(cm, fs), fold_undetermined(cm, fs)
        folds.append(
            {
                "heldout": fs.test_labels,
                "rmse_before": b["rmse"],
                "rmse_after": c["rmse"],
                "gain": 1.0 - c["rmse"] / b["rmse"] if b["rmse"] > 0 else 0.0,
                "max_abs_error_before": b["max_abs_error"],
                "max_abs_error_after": c["max_abs_error"],
                "undetermined_before": und_b,
                "undetermined_after": und_c,
                "determined": bool(max(und_b, und_c) <= FOLD_UNDETERMINED),
            }
        )
        steps.advance()
    gains = [f["gain"] for f in folds]
    n_pos = sum(g > 0 for g in gains)
    out["folds"] = folds
    out["folds_positive"] = f"{n_pos}/{len(folds)}"
    out["mean_fold_gain_raw"] = float(np.mean(gains)) if folds else 0.0
    determined = [f["determined"] for f in folds]
    out["gates"]["folds"], mean_fold = folds_gate(gains, min_gain, determined)
    n_und = len(folds) - sum(determined)
    out["folds_rule"] = (
        f"{n_und} undetermined fold(s) left out; each of the other {len(folds) - n_und} shows a gain"
        if 2 <= len(folds) - n_und < len(folds)
        else "positive in all folds or all but one"
    )
    out["mean_fold_gain"] = mean_fold
    out["fold_gain_floor"] = FOLD_GAIN_FLOOR
    _log(f"  {name}: fold gains {[round(f['gain'], 3) for f in folds]} ({time.time() - t0:.1f} s)", verbose)
    if not out["gates"]["folds"]:
        out["reason"] = f"held-out gain positive in {n_pos} of {len(folds)} folds, mean fold gain {100 * mean_fold:+.1f} %"
        if n_und:
            out["reason"] += f" ({n_und} fold(s) undetermined)"
        return out
    t0 = time.time()
    recs, info = null_records(record, split, current, n_null, rng, max_order)
    null_gains = []
    steps = Steps(f"{name}: null records", len(recs), unit="records")
    for r in recs:
        ns = make_split(r, holdout_residue=holdout_residue, kind=_kind_of(split))  # input alike: the same blocks
        cm0 = _fit_on(None, current, ns, r, new=False)
        cm = refine_model(cm0, ns, max_steps=NULL_REFINE_MAX_STEPS) if refine else cm0
        nm = _fit_on(name, cm0, ns, r, new=True, refine=refine)
        b, c = _held(cm, ns), _held(nm, ns)
        null_gains.append(1.0 - c["rmse"] / b["rmse"] if b["rmse"] > 0 else 0.0)
        steps.advance()
    g = np.asarray(null_gains)
    z = float(stats.norm.ppf(1.0 - fpr))
    # The test is one-sided: only the upper tail of the null gains matters.  A null fit that made the held-out error
    # WORSE (gain < 0: the effect overfitted training) says nothing about how large a gain chance produces, but in
    # mean + z sd it inflated the threshold (independent ambient-drift record: null gains mean -0.43, max 0.06 ->
    # threshold 0.78, the true effect's 0.19 rejected).  The candidate contains the base (effect strength 0), so the
    # gains are clipped at 0 for the quantile.
    gc = np.maximum(g, 0.0)
    q = float(gc.mean() + z * gc.std(ddof=1)) if g.size > 1 else float(g.max())
    threshold = max(q, float(g.max()))
    out["null"] = {
        **info,
        "n_records": int(g.size),
        "gains": g.tolist(),
        "mean": float(g.mean()),
        "sd": float(g.std(ddof=1)) if g.size > 1 else 0.0,
        "max": float(g.max()),
        "quantile_normal": q,
        "quantile_of": "null gains clipped at 0 (one-sided test)",
        "fpr": fpr,
        "threshold": threshold,
        "p_rank": float((1 + np.sum(g >= gain)) / (g.size + 1)),
        "seconds": time.time() - t0,
    }
    out["gates"]["null"] = bool(gain > threshold)
    _log(
        f"  {name}: gain {gain:.3f} vs null mean {g.mean():.3f}, max {g.max():.3f}, threshold {threshold:.3f} "
        f"({time.time() - t0:.1f} s)",
        verbose,
    )
    if not out["gates"]["null"]:
        out["reason"] = (
            f"held-out gain {100 * gain:.1f} % within the null distribution (threshold {100 * threshold:.1f} % at fpr {fpr:g}, "
            f"{g.size} null records)"
        )
        return out
    out["accepted"] = True
    out["reason"] = "passes every gate"
    return out


def lookalike_groups(names) -> tuple[str, ...]:
    """The lookalike groups (`AbstractEffect.lookalikes`) that every effect in ``names`` belongs to, sorted; empty when
    they share none.  A name without groups (``nonlocal_memory``, an effect that declares none) is its own group."""
    groups = [set(getattr(EFFECTS.get(n), "lookalikes", ()) or (n,)) for n in names]
    return tuple(sorted(set.intersection(*groups))) if groups else ()


def _select_calibrated(
    record, split, base, base_te, candidates, fitted, *, min_gain, max_effects, cal, holdout_residue, verbose, noise_sd=None
):
    """Calibrated selection over the fitted candidates; returns ``(selected, chosen, ambiguous, unspecific)``.

    Candidates are tested in order of held-out RMSE (`calibration_gates`); the best accepted one is selected;
    other accepted ones within ``ambiguity`` (10 %) of its held-out RMSE form the ambiguous set (reported, not
    added).  When the ambiguous set shares no lookalike group (`lookalike_groups`), nothing is selected and the set is
    returned as ``unspecific``: effects of unrelated physics that explain the residual alike point at a misfit of the
    base model, not at one of them (measured on clean independent records, issue 13: staircase seed 7, base 1.34x the
    noise held out, creep, asymmetric cooling and input warp within 8 % of each other).  A second effect is added only
    if the combined model passes the same gates against the one-effect model (its null records are simulated from the
    one-effect model).
    """
    rng = np.random.default_rng(cal["seed"])
    fold_cache = {}
    kw = dict(
        min_gain=min_gain,
        fpr=cal["fpr"],
        n_null=cal["n_null"],
        n_folds=cal["n_folds"],
        holdout_residue=holdout_residue,
        fold_cache=fold_cache,
        max_order=cal["ar_max_order"],
        refine=cal.get("refine", False),
        verbose=verbose,
    )
    fitted_c = sorted((c for c in candidates if c.get("fitted")), key=lambda c: c["heldout_rmse"])
    base_h = base_te["rmse"]
    ratio = _at_noise_floor(base_h, noise_sd)
    if ratio is not None:
        reason = (
            f"the base model's held-out RMSE is {ratio:.3g}x the output's noise SD (at most {BASE_AT_FLOOR:g}x: the noise "
            "floor); no structure is left for an effect to explain, so the calibrated test was not run"
        )
        for c in fitted_c:
            gain = 1.0 - c["heldout_rmse"] / base_h if base_h > 0 else 0.0
            c["calibration"] = {"gain": gain, "gates": {"base_above_noise_floor": False}, "accepted": False, "reason": reason}
            c["accepted"] = False
        return [], base, [], []
    # a candidate below the gain gate is rejected at once; only those above it run folds and null records, so the time
    # left is estimated from those (counting all alike said "about 10 min left" one step before the end)
    costly = [base_h > 0 and 1.0 - c["heldout_rmse"] / base_h >= min_gain for c in fitted_c]
    steps = Steps("diagnose: calibrated test", len(fitted_c), unit="effects", weights=[1.0 if k else 0.01 for k in costly])
    for c in fitted_c:
        PROGRESS.info(f"  diagnose: testing {c['name']}")
        m = fitted[c["name"]][0]
        c["calibration"] = calibration_gates(record, split, base, base_te, c["name"], m, _held(m, split), rng=rng, **kw)
        c["accepted"] = c["calibration"]["accepted"]
        steps.advance(note=f"{c['name']}: {'accepted' if c['accepted'] else 'rejected'}")
    accepted = [c for c in fitted_c if c["accepted"]]
    if not accepted:
        return [], base, [], []
    first = accepted[0]
    ambiguous = [c["name"] for c in accepted if c["heldout_rmse"] <= (1.0 + cal["ambiguity"]) * first["heldout_rmse"]]
    if not lookalike_groups(ambiguous):
        return [], base, [], ambiguous
    selected, chosen = [first["name"]], fitted[first["name"]][0]
    cur_te = _held(chosen, split)
    for c in accepted[1:]:
        if len(selected) >= max_effects or NONLOCAL_MEMORY["name"] in selected:  # a replaced base takes no effect
            break
        if c["name"] in ambiguous or c["name"] == NONLOCAL_MEMORY["name"]:
            continue
        m2, _ = fit_extended(chosen, selected + [c["name"]], split, verbose=verbose)
        if kw["refine"]:
            m2 = refine_model(m2, split)
        te2 = _held(m2, split)
        gate = calibration_gates(record, split, chosen, cur_te, c["name"], m2, te2, rng=rng, **kw)
        c["combined_with"] = {
            "effects": selected + [c["name"]],
            "heldout_rmse": te2["rmse"],
            "calibration": gate,
            "accepted": gate["accepted"],
        }
        if gate["accepted"]:
            selected, chosen, cur_te = selected + [c["name"]], m2, te2
    return selected, chosen, ambiguous if len(ambiguous) > 1 else [], []


def _select_legacy(accepted, fitted, split, min_gain, max_effects, verbose, sort=False):
    """Issue-6 rule over the accepted entries (held-out gain >= min_gain and lower BIC on one split): the best one,
    then a second added greedily if it passes the same test against the one-effect model.  Returns ``(selected, chosen)``."""
    if sort:
        accepted = sorted(accepted, key=lambda c: c["heldout_rmse"])
    if not accepted:
        return [], None
    first = accepted[0]["name"]
    selected, chosen = [first], fitted[first][0]
    cur_h, cur_ic = fitted[first][1], fitted[first][2]
    for c in accepted[1:]:
        if len(selected) >= max_effects or NONLOCAL_MEMORY["name"] in selected:  # a replaced base takes no effect
            break
        if c["name"] == NONLOCAL_MEMORY["name"]:
            continue  # a base replacement, not an effect to add
        m2, _ = fit_extended(chosen, selected + [c["name"]], split, verbose=verbose)
        _, te2 = _metrics_pair(m2, split)
        ic2 = information_criteria(m2, split.train)
        ok = te2["rmse"] <= (1.0 - min_gain) * cur_h and ic2["bic"] < cur_ic["bic"]
        c["combined_with"] = {
            "effects": selected + [c["name"]],
            "heldout_rmse": te2["rmse"],
            "delta_bic_vs_previous": ic2["bic"] - cur_ic["bic"],
            "accepted": bool(ok),
        }
        if ok:
            selected, chosen, cur_h, cur_ic = selected + [c["name"]], m2, te2["rmse"], ic2
    return selected, chosen


def _selection_doc(rule, cal, min_gain, candidates, legacy_selected=None, naming="split"):
    """The selection rule as applied, for diagnosis.json (with the legacy decision of each fitted candidate)."""
    legacy = [c["name"] for c in candidates if c.get("legacy_accepted")]
    extra = {} if legacy_selected is None else {"legacy_selected": legacy_selected}
    if rule == "calibrated":
        from ._naming import describe_rule

        extra["naming"] = describe_rule(min_gain) if naming == "whole" else "the gates' best held-out candidate is named"
    if rule == "legacy":
        return {
            "rule": "legacy",
            "description": f"held-out RMSE gain >= {100 * min_gain:g} % on one split and lower training BIC (issue 6); "
            "no calibrated false-positive rate",
            "legacy_accepted": legacy,
        }
    return {
        "rule": "calibrated",
        "description": (
            f"accepted when (1) the held-out RMSE gain >= {100 * min_gain:g} %, (2) the held-out max |error| is not "
            f"raised, (3) the gain is positive in all or all but one of the cross-validation folds and at least "
            f"{100 * min_gain:g} % on average (each fold floored at {100 * FOLD_GAIN_FLOOR:+.0f} %) "
            f"({cal['n_folds']} contiguous time blocks, or the 3 branch residues), both models refitted per fold (a fold "
            "whose held-out prediction its training samples leave undetermined is left out when two others remain, and "
            "then each of those must show a gain), and "
            f"(4) the gain exceeds the (1 - fpr) quantile (normal approximation) and the maximum of the gains the same "
            f"effect reaches on {cal['n_null']} null records (the fitted model without it plus an AR fit of its own "
            "training residuals, refitted like the record)"
        ),
        "false_positive_rate": cal["fpr"],
        "n_null_records": cal["n_null"],
        "n_folds": cal["n_folds"],
        "ambiguity_tolerance": cal["ambiguity"],
        "seed": cal["seed"],
        "note": (
            f"{cal['n_null']} null records is a small number chosen for speed: the quantile at fpr {cal['fpr']:g} is "
            "extrapolated from their mean and standard deviation, not counted"
        ),
        "legacy_accepted": legacy,
        **extra,
    }


def _decisions(candidates, selected, ambiguous, rule, unspecific=(), tolerance=CALIBRATED_DEFAULTS["ambiguity"]):
    """One plain decision per candidate, so that a report never lists several 'accepted' beside one selected."""
    for c in candidates:
        n = c["name"]
        if n in unspecific:
            others = ", ".join(x for x in unspecific if x != n)
            c["decision"] = (
                f"passes; not selected: {others} explain the residual as well (within {100 * tolerance:g} % held-out RMSE) and share no "
                "lookalike group with it: structure the base model misses, not the signature of one effect"
            )
        elif n in selected:
            c["decision"] = "selected" if selected[0] == n else f"selected (added to {selected[0]})"
        elif not c.get("fitted"):
            c["decision"] = "not fitted (" + (
                "no score-test evidence)" if not c.get("plausible") else "ranked below max_candidates)"
            )
        elif c.get("accepted") and n in ambiguous:
            c["decision"] = f"passes; ambiguous with {selected[0]} (data cannot separate them)"
        elif c.get("accepted"):
            c["decision"] = f"passes alone; not added ({', '.join(selected)} selected)"
        elif rule == "calibrated":
            c["decision"] = "rejected: " + c.get("calibration", {}).get("reason", "not accepted")
        else:
            c["decision"] = "rejected: held-out gain < min_gain or BIC not lower"


# -- diagnosis -------------------------------------------------------------------------


def _metrics_pair(model, split):
    tr, _ = score(model, split.train)
    te, _ = score(model, split.test)
    return tr, te


@blas_limited
def diagnose(
    record,
    *,
    effects=None,
    max_candidates=None,
    min_gain=0.05,
    max_effects=2,
    p_threshold=None,
    holdout_residue=2,
    refit=True,
    verbose=False,
    rule="calibrated",
    fpr=CALIBRATED_DEFAULTS["fpr"],
    n_null=CALIBRATED_DEFAULTS["n_null"],
    n_folds=CALIBRATED_DEFAULTS["n_folds"],
    seed=0,
    compare_legacy=False,
    screen=True,
    refine=True,
    unexplained=True,
    naming="whole",
    reference=True,
    split="auto",
) -> Diagnosis:
    """Full diagnosis of one record; returns a `Diagnosis` (selected effects, models, split, diagnosis.json content).

    ``screen``: the base model's output orientation, hysteresis input and thermal start are first screened
    on the training samples as `smafl fit` does (`screened_base`); False keeps the fixed start of earlier versions.
    ``refine`` (with ``screen``): the base is refined jointly with its thresholds, tilts and a fitted operator
    memory (`refined_base`), and every candidate effect model with the same freedom (`refine_model`), on the
    null records too.

    ``Diagnosis.base`` / ``.extended`` are fitted on the training part of the split (the
    held-out figures are theirs).  With ``refit`` the selected structure is
    also refitted on the whole record (`refit_whole_record`): ``report["deployed"]``
    and ``Diagnosis.deployed_base`` / ``.deployed_extended``.

    ``rule="calibrated"`` (default, issue 13) accepts an effect only through `calibration_gates` (held-out gain
    >= ``min_gain``, max error not raised, gain positive in all or all but one of ``n_folds`` folds, gain above
    the (1 - ``fpr``) quantile of ``n_null`` parametric-bootstrap null records; ``seed`` seeds the nulls);
    ``rule="legacy"`` is the rule of issue 6 (held-out gain >= ``min_gain`` on one split and lower BIC);
    ``compare_legacy`` also records what it would select (``report["selection"]["legacy_selected"]``).

    ``naming="whole"`` (default, calibrated rule): when the gates accept an effect, the name is chosen on the whole
    record (`smafl_jax.diagnosis._naming`: every fitted candidate refitted on every sample, the largest gain named if
    it is >= ``min_gain``, else nothing); ``naming="split"`` keeps the gates' best held-out candidate (earlier versions).

    ``reference`` (calibrated rule): when the gates accept an effect, `smafl fit`'s default structure is fitted on the
    same split (`smafl_jax.diagnosis._reference`); where it holds out at the noise floor (`BASE_AT_FLOOR`) the
    acceptance is withdrawn and the naming goes on as for a base at the floor (``report["base"]["reference_fit"]``).

    ``split`` (records without a branch column): ``"auto"`` (default since session 70) the last 30 % unless the first
    70 % covers less than 90 % of its input levels and directions, then every third of ten blocks (`make_split`);
    ``"time"`` / ``"interleaved"`` force one (with ``"interleaved"`` the fold test is interleaved too).

    ``unexplained`` (after the selection, never changing it): ``report["unexplained"]`` says whether the held-out
    residual still has structure, names its strongest correlate and scores a generic, clearly labelled ridge
    regression of the residual on the candidate signals, fitted on the training residual (`smafl_jax.diagnosis._unexplained`).
    """
    if rule not in SELECTION_RULES:
        raise UserInputError(f"rule must be one of {SELECTION_RULES}, got {rule!r}")
    if not 0.0 < fpr < 0.5:
        raise UserInputError(f"fpr must be in (0, 0.5), got {fpr!r}")
    if n_null < 2:
        raise UserInputError(f"n_null must be >= 2, got {n_null!r}")
    if naming not in NAMING_RULES:
        raise UserInputError(f"naming must be one of {NAMING_RULES}, got {naming!r}")
    check_record(record)
    t_start = time.time()
    base0, base_rule = choose_base(record)
    rate_free = is_rate_free(record)
    split = make_split(record, holdout_residue=holdout_residue, kind=split)
    warnings = []
    if effects is None:
        names = applicable_effects(base0, split, rate_free)
    else:
        unknown = [n for n in effects if n not in EFFECTS and n != NONLOCAL_MEMORY["name"]]
        if unknown:
            raise UserInputError(f"unknown effect(s) {unknown}; catalogue: {list(EFFECTS) + [NONLOCAL_MEMORY['name']]}")
        ok = set(applicable_effects(base0, split, rate_free))
        names = [n for n in dict.fromkeys(effects) if n in ok]
        for n in dict.fromkeys(effects):
            if n not in ok and not (n == NONLOCAL_MEMORY["name"] and rate_free):
                warnings.append(
                    f"effect {n!r} does not apply to this record: {_not_applicable_reason(n, base0, rate_free, split)}"
                )
    offer_preisach = rate_free and (effects is None or NONLOCAL_MEMORY["name"] in effects)
    if effects is not None and not names and not offer_preisach:
        raise UserInputError("; ".join(warnings) + "; nothing left to test")
    for w in warnings:
        _log(f"warning: {w}", verbose)
    _log(
        f"diagnose: {len(record)} samples, base {type(base0).__name__}, split {split.kind}, {len(names)} applicable effects",
        verbose,
    )
    k1_grid = (0.01, 0.03, 0.1, 0.3) if thermal_of(base0) is not None else None
    screened = None
    if screen:
        base0, screened = screened_base(base0, split, verbose)
        if screened is not None:
            k1_grid = None  # the screened k1 (searched jointly with the thermal start) is the simplex's start
    base, base_info = fit_extended(base0, [], split, k1_grid=k1_grid, verbose=verbose)
    refine = bool(refine and screened is not None)
    cand_start = base
    if refine:
        base, cand_start, base_info["refinement"] = refined_base(base, base0, split, verbose)
        base, base_info["refinement"]["passes"] = converged_base(base, split, verbose)
    base_tr, base_te = _metrics_pair(base, split)
    base_ic = information_criteria(base, split.train)
    _, res_tr = score(base, split.train)
    _, res_te = score(base, split.test)

    # residual diagnostics on train and held-out
    def resid_block(segs, resid):
        u = np.concatenate([s.u[s.mask] for s in segs])
        out = {"whiteness": whiteness_report(resid, u)}
        sigs = {}
        for s in segs:
            yh = simulate_segment(base, s)
            x = np.asarray(base.hysteresis_input(jnp.asarray(s.u), jnp.asarray(s.dt))) if thermal_of(base) is not None else None
            cs = candidate_signals(s.time, s.u, yh, s.dt, x=x, extra=s.extra)
            for k, v in cs.items():
                sigs.setdefault(k, []).append(v[s.mask])
        sigs = {k: np.concatenate(v) for k, v in sigs.items() if len(v) == len(segs)}
        out["signal_correlations"] = signal_correlations(resid, sigs)
        return out

    residuals = {"train": resid_block(split.train, res_tr), "heldout": resid_block(split.test, res_te)}
    evidence = effect_evidence(base, split, names, res_tr)
    ranked = sorted(names, key=lambda n: -evidence[n]["partial_r2"])
    if refine and max_candidates is None and p_threshold is None:
        # With the refined base every applicable effect is fitted; the score test only orders them.  Measured on the
        # independent plant: the true effect ranked 10th of 12 (p 0.03) and was then the only one accepted (gain 25 %).
        p_threshold, max_candidates = 1.0, len(ranked)
    p_threshold = LEGACY_SCREEN["p_threshold"] if p_threshold is None else p_threshold
    max_candidates = LEGACY_SCREEN["max_candidates"] if max_candidates is None else max_candidates
    plausible = [n for n in ranked if evidence[n]["p_value"] < p_threshold]
    to_fit = plausible[:max_candidates]
    _log(
        "evidence ranking: "
        + ", ".join(f"{n} (R2 {evidence[n]['partial_r2']:.3f}, p {evidence[n]['p_value']:.1e})" for n in ranked),
        verbose,
    )

    base_h = base_te["rmse"]
    candidates = []
    fitted = {}
    steps = Steps("diagnose: fitting candidate effects", len(to_fit) + int(offer_preisach), unit="effects")
    for name in ranked:
        entry = {"name": name, "evidence": evidence[name], "plausible": name in plausible, "fitted": name in to_fit}
        if name in to_fit:
            # symmetric: the candidate starts where the base's refinement started and gets the same freedom (a base
            # refined first absorbs part of an effect that the candidate, started from it, cannot take back)
            m, info = fit_extended(cand_start, [name], split, verbose=verbose)
            if refine:
                m = refine_model(m, split)
                m, info = _from_refined_base_too(m, info, base, cand_start, name, split, verbose)
            tr, te = _metrics_pair(m, split)
            ic = information_criteria(m, split.train)
            entry.update(
                {
                    "train_rmse": tr["rmse"],
                    "heldout_rmse": te["rmse"],
                    "heldout_e_r_percent": te["e_r_percent"],
                    "heldout_gain": 1.0 - te["rmse"] / base_h if base_h > 0 else 0.0,
                    "delta_bic": ic["bic"] - base_ic["bic"],
                    "delta_aic": ic["aic"] - base_ic["aic"],
                    "added_parameters": ic["k"] - base_ic["k"],
                    "parameters": _effect_params(m.get(name)),
                    "fit": info,
                }
            )
            entry["accepted"] = bool(te["rmse"] <= (1.0 - min_gain) * base_h and entry["delta_bic"] < 0)
            entry["legacy_accepted"] = entry["accepted"]
            fitted[name] = (m, te["rmse"], ic)
            steps.advance(note=name)
        candidates.append(entry)
    if offer_preisach:
        entry, pm = _fit_nonlocal_memory(record, split, base_h, base_ic, min_gain, verbose)
        steps.advance(note=entry["name"])
        entry["legacy_accepted"] = entry["accepted"]
        candidates.append(entry)
        fitted[entry["name"]] = pm

    accepted = sorted([c for c in candidates if c.get("accepted")], key=lambda c: c["heldout_rmse"])
    selected, chosen, ambiguous, unspecific = [], base, [], []
    cal = {**CALIBRATED_DEFAULTS, "fpr": fpr, "n_null": n_null, "n_folds": n_folds, "seed": seed, "refine": refine}
    if rule == "calibrated":
        noise_sd = noise_floor([record])["sd"]
        if (ratio := _at_noise_floor(base_h, noise_sd)) is not None:
            warnings.append(
                f"the base model is at the noise floor: held-out RMSE {base_h:.4g}, {ratio:.3g}x the output's "
                f"noise SD ({noise_sd:.4g}, estimated from the data); the held-out gates were not run (at most "
                f"{BASE_AT_FLOOR:g}x){'' if naming == 'whole' else '; no effect was tested'}"
            )
        selected, chosen, ambiguous, unspecific = _select_calibrated(
            record,
            split,
            base,
            base_te,
            candidates,
            fitted,
            min_gain=min_gain,
            max_effects=max_effects,
            cal=cal,
            holdout_residue=holdout_residue,
            verbose=verbose,
            noise_sd=noise_sd,
        )
    elif accepted:
        selected, chosen = _select_legacy(accepted, fitted, split, min_gain, max_effects, verbose)
    naming_doc = None
    # named on the whole record: what the gates accepted, or, with the base at the noise floor on the held-out block
    # (the gates not run), what the whole record shows (independent records: true effects held out at +8-9 % there)
    at_floor = rule == "calibrated" and _at_noise_floor(base_h, noise_sd) is not None
    reference_doc, withdrawn = None, {}
    if rule == "calibrated" and reference and selected and not at_floor:
        # what the gates accepted may only make up for the diagnosis's lighter base fit (`_reference`)
        from ._reference import reference_heldout, withdrawal

        _log("diagnose: smafl fit's default structure on the same split (reference)", verbose)
        reference_doc = reference_heldout(record, split, noise_sd)
        withdrawn, warning = withdrawal(selected, reference_doc, base_h / noise_sd if noise_sd else np.nan, BASE_AT_FLOOR)
        if withdrawn:
            warnings.append(warning)
            selected, chosen, ambiguous, at_floor = [], base, [], True
    if rule == "calibrated" and naming == "whole" and (selected or at_floor) and NONLOCAL_MEMORY["name"] not in selected:
        from ._naming import name_on_whole_record

        pool = [n for n in fitted if n != NONLOCAL_MEMORY["name"]]
        naming_doc, (selected, ambiguous), warning = name_on_whole_record(
            record,
            base,
            pool,
            selected,
            ambiguous,
            min_gain=min_gain,
            noise_sd=noise_sd,
            heldout_gain={c["name"]: c["heldout_gain"] for c in candidates if "heldout_gain" in c},
            refine=refine,
            verbose=verbose,
        )
        chosen = base if not selected else chosen if selected == naming_doc["split_selected"] else fitted[selected[0]][0]
        naming_doc["base_at_noise_floor"] = at_floor
        if warning:
            warnings.append(warning)
    legacy_selected = None
    if compare_legacy and rule == "calibrated":
        import copy

        legacy_selected = _select_legacy(
            [copy.deepcopy(c) for c in candidates if c.get("legacy_accepted")],
            fitted,
            split,
            min_gain,
            max_effects,
            verbose,
            sort=True,
        )[0]
    _decisions(candidates, selected, ambiguous, rule, unspecific, cal["ambiguity"])
    for c in candidates:
        if c["name"] in withdrawn:
            c["decision"] = f"passes the gates; not selected: {withdrawn[c['name']]}"
    if naming_doc is not None:
        from ._naming import naming_decisions

        naming_decisions(candidates, naming_doc)
    if (gap_warning := generalisation_warning(base_tr["rmse"], base_te["rmse"])) is not None:
        warnings.append(gap_warning)
    if unspecific:
        warnings.append(
            f"nothing selected although {', '.join(unspecific)} each pass the calibrated test: they explain the residual "
            f"alike (within {100 * cal['ambiguity']:g} % held-out RMSE) and share no lookalike group, so the residual is structure the base model "
            "misses rather than the signature of one of them (diagnosis.json 'unspecific'; the unexplained report names "
            "its strongest correlate)"
        )
    ext_tr, ext_te = _metrics_pair(chosen, split)
    _, ext_res_te = score(chosen, split.test)
    _, ext_res_tr = score(chosen, split.train)

    strongest = _strongest_correlate(
        residuals["heldout"]["signal_correlations"] if not selected else resid_after(chosen, split, ext_res_te)
    )
    noise = noise_floor([record], base_train=base_tr, base_heldout=base_te, extended_train=ext_tr, extended_heldout=ext_te)
    noise["base_structure_left_sd"] = left = structure_left_sd(noise.get("base_train_ratio"))
    if not selected and left is not None and left < DETECTABLE_STRUCTURE_SD:
        warnings.append(
            f"nothing named, and the base model leaves {left:.2g} noise SD of structure on its training samples (its "
            f"training RMSE {noise['base_train_ratio']:.3g}x the output's noise SD): whatever an effect changes in this "
            "record the base's own freedom has mimicked, so 'none' means no effect this record can tell from the base, "
            "not that the actuator has none (a longer record, or one driven across more levels and rates, may separate it)"
        )
    if selected and (noise["extended_train_ratio"] or 0.0) > NOISE_FLOOR_WARN:
        # measured on clean independent records (issue 13): every false selection sat on a base at 2x the noise or more;
        # a true effect brings the fit down to the noise, so misfit left after the selection is worth a warning
        warnings.append(
            f"with the selected effect the model still stays at {noise['extended_train_ratio']:.3g}x the output's noise "
            f"SD ({noise['sd']:.4g}, estimated from the data) on its own training samples (base "
            f"{noise['base_train_ratio']:.3g}x): structure is left that neither expresses, and the selection may absorb "
            "part of that misfit rather than name a physical effect of this record"
        )
    result = {
        "record": {
            "n_samples": len(record),
            "sample_time_s": record.dt,
            "input_column": record.input_name,
            "output_column": record.output_name,
            "path": record.path,
            "sha256": record.sha256,
        },
        "base": {
            "model": type(base0).__name__,
            "rule": base_rule,
            "rate_free": rate_free,
            "train": base_tr,
            "heldout": base_te,
            "train_rmse": base_tr["rmse"],
            "heldout_rmse": base_te["rmse"],
            "heldout_over_train": base_te["rmse"] / base_tr["rmse"] if base_tr["rmse"] > 0 else None,
            "information_criteria": base_ic,
            "fit": base_info,
            "start": _start_doc(base, screened),
            "reference_fit": reference_doc,
        },
        "split": {
            "kind": split.kind,
            "rule": split.rule,
            "train": split.train_labels,
            "heldout": split.test_labels,
            "coverage": split_coverage(split),
            "state_coverage": state_coverage(base, split),
        },
        "residuals": residuals,
        "applicable_effects": names,
        "evidence_ranking": ranked,
        "candidates": candidates,
        "selected": selected,
        "extended": {
            "effects": selected,
            "train": ext_tr,
            "heldout": ext_te,
            "train_rmse": ext_tr["rmse"],
            "heldout_rmse": ext_te["rmse"],
            "information_criteria": (
                fitted[selected[0]][2] if NONLOCAL_MEMORY["name"] in selected else information_criteria(chosen, split.train)
            ),
            "parameters": {
                n: (_preisach_params(fitted[n][3]) if n == NONLOCAL_MEMORY["name"] else _effect_params(chosen.get(n)))
                for n in selected
            },
            "residuals_heldout": {"whiteness": whiteness_report(ext_res_te, np.concatenate([s.u[s.mask] for s in split.test]))},
        },
        "improvement": {
            "heldout_rmse_ratio": ext_te["rmse"] / base_te["rmse"] if base_te["rmse"] > 0 else 1.0,
            "heldout_rmse_reduction_percent": 100.0 * (1.0 - ext_te["rmse"] / base_te["rmse"]) if base_te["rmse"] > 0 else 0.0,
            "heldout_e_r_before": base_te["e_r_percent"],
            "heldout_e_r_after": ext_te["e_r_percent"],
        },
        "strongest_remaining_correlate": strongest,
        "noise": noise,
        "ambiguous": ambiguous,
        "unspecific": unspecific,
        "warnings": warnings,
        "selection": _selection_doc(rule, cal, min_gain, candidates, legacy_selected, naming),
        "naming": naming_doc,
        "settings": {
            "max_candidates": max_candidates,
            "min_gain": min_gain,
            "max_effects": max_effects,
            "p_threshold": p_threshold,
            "rule": rule,
        },
        "seconds": time.time() - t_start,
    }
    correction = None
    if unexplained:
        from ._unexplained import unexplained_report

        result["unexplained"], correction = unexplained_report(
            chosen,
            split,
            ext_res_tr,
            ext_res_te,
            selected=selected,
            whiteness=result["extended"]["residuals_heldout"]["whiteness"],
            strongest=strongest,
            simulate=simulate_segment,
            min_gain=min_gain,
            heldout_noise_ratio=noise.get("extended_heldout_ratio"),
        )
    unwrapped = chosen if selected else base.base
    base_all = ext_all = None
    if refit:
        base_all, ext_all, info = refit_whole_record(record, base.base, unwrapped, result, verbose)
        result["deployed"] = info
    from ._result import Diagnosis, ResidualArrays  # here: _result imports Split from this module

    return Diagnosis(
        selected=tuple(selected),
        base=base.base,
        extended=unwrapped,
        split=split,
        report=result,
        residuals=ResidualArrays(res_tr, res_te, ext_res_tr, ext_res_te, correction),
        deployed_base=base_all,
        deployed_extended=ext_all,
    )


def _preisach_params(info):
    return {
        "method": info.get("method", "penalised"),
        "n_levels": info["n_levels"],
        "lam": info["lam"],
        "relay_width": info.get("width", 0.0),
        "effective_dof": info["dof"],
        "n_nonzero_weights": info["n_nonzero"],
    }


def _fit_nonlocal_memory(record, split, base_h, base_ic, min_gain, verbose):
    """Fit the Preisach replacement (inner CV on the training segments) and score it like an effect candidate."""
    t0 = time.time()
    u = np.asarray(record.u, float)
    pm, info = cv_fit_preisach(split.train, float(u.min()), float(u.max()))
    tr, te = _metrics_pair(pm, split)
    ic = information_criteria(pm, split.train, k=info["dof"])
    _log(
        f"  fit nonlocal_memory (Preisach): n_levels {info['n_levels']}, {info['method']}, lam {info['lam']}, dof {info['dof']:.1f}, "
        f"held-out RMSE {te['rmse']:.4g}, {time.time() - t0:.1f} s",
        verbose,
    )
    nan = float("nan")
    entry = {
        "name": NONLOCAL_MEMORY["name"],
        "base_replacement": True,
        "plausible": True,
        "fitted": True,
        "evidence": {
            "partial_r2": nan,
            "corr": nan,
            "n_eff": nan,
            "lm_stat": nan,
            "p_value": nan,
            "probe": {},
            "note": "base replacement (not nested in the base): no score test; always fitted on rate-free records",
        },
        "train_rmse": tr["rmse"],
        "heldout_rmse": te["rmse"],
        "heldout_e_r_percent": te["e_r_percent"],
        "heldout_gain": 1.0 - te["rmse"] / base_h if base_h > 0 else 0.0,
        "delta_bic": ic["bic"] - base_ic["bic"],
        "delta_aic": ic["aic"] - base_ic["aic"],
        "added_parameters": ic["k"] - base_ic["k"],
        "parameters": _preisach_params(info),
        "fit": {"inner_cv": info["inner_cv"], "cv_table": info["cv_table"], "seconds": time.time() - t0},
    }
    entry["accepted"] = bool(te["rmse"] <= (1.0 - min_gain) * base_h and entry["delta_bic"] < 0)
    return entry, (pm, te["rmse"], ic, info)


def whole_record_split(record):
    """Every sample of ``record`` as training data (branch records: one segment per branch)."""
    lc = load_column(record)
    if "branch" in record.extra:
        b = np.asarray(record.extra["branch"]).astype(int)
        labels = list(dict.fromkeys(b.tolist()))
        segs = [_segment(record, np.flatnonzero(b == k), load_col=lc) for k in labels]
    else:
        labels = [f"0..{len(record) - 1}"]
        segs = [_segment(record, np.arange(len(record)), load_col=lc)]
    return Split("all", "every sample (training and held-out parts together)", segs, [], labels, [])


def refit_whole_record(record, base, ext, result, verbose=False):
    """Deployed models: the base and the selected structure refitted on every sample of the record.

    The structure (effects, or the Preisach replacement) stays as chosen on the
    split; effect parameters restart from their split fit; the Preisach grid,
    penalty or Everett interpolant is chosen again by its inner CV over all
    segments.  The held-out figures of the diagnosis remain those of the
    split fit: the deployed model has no held-out data left, and with more
    data it is expected to predict new data at least as well (not measured
    here).  Returns ``(base_all, ext_all, info)``.
    """
    t0 = time.time()
    PROGRESS.info("  diagnose: refitting the chosen structure on the whole record")
    full = whole_record_split(record)
    base_all = fit_extended(ExtendedModel.of(base), [], full)[0].base
    preisach_cv = None
    if NONLOCAL_MEMORY["name"] in result["selected"]:
        # the grid and penalty are chosen again by the same inner CV, now over every branch: each inner fold then
        # predicts a branch between two trained neighbours, the situation of a new branch from the same rig
        u = np.asarray(record.u, float)
        ext_all, pinfo = cv_fit_preisach(
            full.train, float(u.min()), float(u.max()), linear=ext.linear, init=ext.init, ramp=bool(float(ext.width) > 0)
        )
        preisach_cv = {**_preisach_params(pinfo), "inner_cv": pinfo["inner_cv"], "inner_cv_rmse": pinfo["chosen"]["cv_rmse"]}
    elif not result["selected"]:
        ext_all = base_all
    else:
        ext_all = fit_extended(ext, list(ext.effect_names), full)[0]
    wrap = lambda m: ExtendedModel(m, ()) if m is base_all else m  # the base is scored as on the split; the rest as is
    info = {
        "fitted_on": full.rule,
        "segments": full.train_labels,
        "n_samples": int(sum(s.mask.sum() for s in full.train)),
        "base_rmse_all": score(wrap(base_all), full.train)[0]["rmse"],
        "extended_rmse_all": score(wrap(ext_all), full.train)[0]["rmse"],
        "extended_parameters": (
            {NONLOCAL_MEMORY["name"]: preisach_cv} if preisach_cv else _effect_params_all(ext_all, result["selected"])
        ),
        "seconds": time.time() - t0,
    }
    _log(
        f"refit on the whole record: base RMSE {info['base_rmse_all']:.4g}, extended RMSE {info['extended_rmse_all']:.4g} "
        f"({info['seconds']:.1f} s)",
        verbose,
    )
    return base_all, ext_all, info


def _effect_params_all(model, names):
    return {n: _effect_params(model.get(n)) for n in names}


def split_coverage(split, tol=0.02, warn_below=0.9):
    """How much of the held-out part the training part has seen (input level and direction); see `data.split.coverage`."""
    from ..data.split import coverage

    return coverage(split, tol=tol, warn_below=warn_below)


def state_coverage(model, split):
    """`data.split.branch_coverage` of the held-out samples on the base model's thermal state (what its hysteresis
    sees) for a time-block or interleaved split, or None (no thermal stage, or branch records).

    Why beside `split_coverage` (on the input): a PWM drive switches up and down every period, so its voltage covers
    every branch while the state it heats may only have risen in training (see `branch_coverage`)."""
    from ..data.split import branch_coverage

    if thermal_of(model) is None or not hasattr(model, "hysteresis_input") or split.kind not in ("time", "interleaved"):
        return None
    (first,), (seg,) = split.train, split.test  # a training prefix (or the whole record, masked); the whole record, masked
    k = first.u.shape[0]
    if not np.array_equal(first.u, seg.u[:k]):
        return None
    train = np.zeros(seg.u.shape[0], bool)
    train[:k] = first.mask
    x = np.asarray(model.hysteresis_input(jnp.asarray(seg.u), jnp.asarray(seg.dt)))
    if not np.all(np.isfinite(x)):
        return None
    return branch_coverage(x, train, seg.mask, what="base model's thermal state (its hysteresis input)")


def resid_after(model, split, resid):
    sigs = {}
    for s in split.test:
        yh = simulate_segment(model, s)
        cs = candidate_signals(s.time, s.u, yh, s.dt, extra=s.extra)
        for k, v in cs.items():
            sigs.setdefault(k, []).append(v[s.mask])
    sigs = {k: np.concatenate(v) for k, v in sigs.items() if len(v) == len(split.test)}
    return signal_correlations(resid, sigs)


def _strongest_correlate(corrs):
    if not corrs:
        return None
    name = max(corrs, key=lambda k: abs(corrs[k]["corr"]))
    return {"signal": name, **corrs[name]}


def _effect_params(e):
    if e is None:
        return {}
    return {k: float(np.asarray(getattr(e, k))) for k in e.parameters if hasattr(e, k)}


# -- synthetic records with an undeclared effect (tests, experiments) ------------------


def synthetic_effect_record(truth, drives, effect, seed, *, dt=0.5, noise_sd=0.003, order=("steps", "main_loop", "minor_loop")):
    """Record from the true cascade plus one effect (``effect=None``: none), seeded; returns ``(Record, true_model)``.

    ``drives`` is ``datasets/generate.py``'s ``drives()`` dict; the drives are
    concatenated in ``order`` (all start and end at 0 V).
    """
    from ..data._data import Record

    rng = np.random.default_rng(seed)
    u = np.concatenate([np.asarray(drives[k][1], float) for k in order])
    t = np.arange(u.size) * dt
    y_base = np.asarray(_sim(ExtendedModel(truth, ()), jnp.asarray(u), jnp.asarray(dt), None))
    lo, hi = float(y_base.min()), float(y_base.max())
    sign = 1.0 if rng.random() < 0.5 else -1.0
    extra, load = {}, None
    if effect is None:
        eff = None
    else:
        ctx = {"dt": dt, "n": u.size, "y_lo": lo, "y_hi": hi, "sign": sign}
        eff, extra = _effect_class(effect).synthesise(rng, ctx)
        lc = next((k for k in extra if any(n in k.lower() for n in LOAD_NAMES)), None)
        load = None if lc is None else extra[lc]
    true = ExtendedModel(truth, () if eff is None else (eff,))
    y = np.asarray(_sim(true, jnp.asarray(u), jnp.asarray(dt), None if load is None else jnp.asarray(load)))
    y = y + noise_sd * rng.standard_normal(y.shape)
    rec = Record.from_arrays(t, u, y, input_name="voltage_V", output_name="displacement_mm", extra=extra)
    return rec, true
