"""Hysteresis protocol: the operations every consumer needs of a hysteresis model (diffrax-style).

`AbstractHysteresis` is the abstract `equinox.Module` that fitting (`smafl_jax.fit`), sampling
(`Posterior`), control (`plant_step`, `IICompensator`), diagnosis and the effect catalogue
(`ExtendedModel`) program against; the concrete models (`EUPI`, `Preisach`, `GaussianPreisach`, `PhaseFraction`) are final
classes.
A hysteresis model is a rate-independent map with memory from a scalar input record ``x(k)`` to an
output ``y(k)``, linear in its *linear weights* for fixed grids:

    y = features(x) @ linear_weights()

with the same state rule as the evaluation.  Its contract:

- ``features(x)`` ``(T, p)``, ``linear_weights()`` ``(p,)``, ``with_linear_weights(theta)``,
  ``nonnegative_columns()`` (bool ``(p,)``: the weights that must stay >= 0) and ``linear_fields()``
  (the fields that hold the linear weights);
- ``fixed_fields(train=())``: fields never trained or sampled (grids, spans); optional groups named in
  `trainable_groups` (EUPI: ``"thresholds"``, ``"tilts"``) are trained when named in ``train``;
- the state rule: ``initial_state(x0)`` is the state *before* the first sample given the first input
  (the ``init`` rule), ``step(state, x) -> (state, y)`` is one pure sample, so that
  ``lax.scan(step, initial_state(x[0]), x)`` equals ``simulate(x)`` (tested for every model);
- ``simulate(u, dt=None)`` / ``__call__``: the whole-record evaluation (``dt`` ignored);
- ``orientation`` (+1: the output rises with the input for non-negative weights, -1: it falls), which
  the integral-inverse compensator uses as the slope sign of its forward model;
- ``from_range(u_min, u_max)`` (untrained model for an input range) and ``with_range`` (the same
  structure rescaled to another range);
- optional, with defaults taken from the above: ``weight_scales()`` and ``nonlinear_priors()`` (the
  sampler's priors: the weights' follow from their signs and scales, other trained fields are named
  here) and ``describe()`` (the lines of a fit report).

Composite models expose their hysteresis the same way: ``model.hysteresis`` (a hysteresis model is
its own), ``model.with_hysteresis(h)`` and ``model.hysteresis_input(u, dt)``; `hysteresis_of`
returns ``None`` for models without one (the Joule lag).  The consumers ask the model, never its
class (issue 12): ``plant_parts()`` (the per-sample stages of the closed loop), ``extendable`` (it
may be the base of an `ExtendedModel`), ``evaluation_methods`` (the forms `with_method` accepts).

Registry: the concrete classes are named in `smafl_jax._choices.HYSTERESIS` (a JAX-free module, so
``smafl fit --help`` lists them without importing JAX); `hysteresis_models` resolves them.
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Collection
from importlib import import_module
from types import MappingProxyType
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import _config  # noqa: F401

__all__ = [
    "AbstractHysteresis",
    "AbstractScaledShape",
    "hysteresis_of",
    "thermal_of",
    "hysteresis_models",
    "hysteresis_class",
    "column_weight_scales",
    "linear_field_columns",
]


class AbstractHysteresis(eqx.Module):
    """Rate-independent hysteresis ``x -> y`` with memory, linear in its weights for fixed grids (see module docstring)."""

    # Fields every implementation declares itself (an `eqx.AbstractVar` here would move them to the front of
    # the subclass's dataclass fields, changing its positional __init__ and JSON order): ``u_ref``, ``u_span``
    # (normalisation s = (x - u_ref) / u_span), ``init`` (initial-state rule, static) and ``orientation``
    # (+1 / -1, static: the sign of the non-negative part of the features).

    # Class constants (plain attributes, not annotated: a ClassVar annotation would enter every subclass's
    # __dataclass_fields__).
    #: Initial-state rules the model accepts as ``init`` (the first is the default).
    INITS = ()
    #: The rules among `INITS` that need no extra parameter: a fit's start screening tries each of them
    #: (`smafl_jax.identify.screen_start`), since the branch a record starts on is a property of the record.
    RULE_INITS = ()
    #: Optional groups of grid fields a fit may train on request (``{"thresholds": ("r_sym", "r_asym")}``).
    trainable_groups = MappingProxyType({})
    #: ``features(x, threshold_scale=...)`` accepted: thresholds scaled per sample (the ``rate_dependence`` effect).
    scalable_thresholds = False
    #: The output is ``features(u, dt) @ hysteresis.linear_weights()`` (true of every hysteresis model and cascade).
    linear_in_weights = True
    #: May be the base of an `ExtendedModel` (catalogue effects wrap it; an extended model itself is not).
    extendable = True
    #: Evaluation forms `with_method` switches between (`model_with_method`); () for a model with one form.
    evaluation_methods = ()
    #: `smafl fit` refines the profiled start jointly (gradient steps on weights, grid groups, thermal rate and start).
    #: False for a class whose only nonlinear parameters in a fit are the thermal rate and start, which the profiled
    #: start already optimises with the weights solved exactly: the joint steps then cost time and gain nothing.
    refine_jointly = True
    #: ``--model auto`` fits this class behind the Joule lag on a drive voltage (``cascade-NAME``).  False for a class
    #: that auto leaves out there (its measurement on the class); ``--model cascade-NAME`` still fits it.
    compared_behind_lag = True

    def orientation_sign(self):
        """The orientation as the factor on the signed feature columns: ``float(orientation)`` in a user's model, the
        leaf ``sign`` in its `compile_form`."""
        sign = getattr(self, "sign", None)
        return float(self.orientation) if sign is None else sign

    def compile_form(self) -> AbstractHysteresis:
        """The same model with its orientation as data (leaf ``sign``, ``orientation`` 0) instead of a static choice.

        Why: static fields are part of the tree structure `jax.jit` keys its programs on, so the start screening's two
        output signs compiled every design and simulation twice, and a record whose sign stayed open every LM solve
        too.  The jitted entry points of the fit take this form (`smafl_jax.models.compile_form`).  A class without
        a ``sign`` field keeps its static orientation."""
        if getattr(self, "sign", True) is not None:  # no such field, or already the compile form
            return self
        return dataclasses.replace(self, orientation=0, sign=jnp.asarray(float(self.orientation)))

    def user_form(self) -> AbstractHysteresis:
        """Inverse of `compile_form` (needs a concrete ``sign``)."""
        if getattr(self, "sign", None) is None:
            return self
        return dataclasses.replace(self, orientation=1 if float(self.sign) > 0 else -1, sign=None)

    def screening_grid(self) -> AbstractHysteresis:
        """A cheaper model of the same class and range that the start screening compares its candidates on (output
        sign, hysteresis input, memory rule, thermal start; `smafl_jax.identify.screen_start`); the chosen start is
        then finished on this model's own grid (`on_grid_of`).  Default: the model itself."""
        return self

    def on_grid_of(self, fine: AbstractHysteresis) -> AbstractHysteresis:
        """This model's range, orientation and initial-state rule on the grid of ``fine`` (the model `screening_grid`
        was taken from), weights untrained.  Default: itself (its screening grid is its own)."""
        del fine
        return self

    def adopt(self, screened: AbstractHysteresis) -> tuple[AbstractHysteresis, ...]:
        """Starts of this model's structure from ``screened``, the `screening_grid` model after the start screening
        (its orientation, initial-state rule and what its weights say); the fit profiles each on the data and keeps
        the best (`smafl_jax.identify._choose._on_own_grid`).  Default: ``screened`` on this model's grid
        (`on_grid_of`), one start."""
        return (screened.on_grid_of(self),)

    @classmethod
    def for_cascade(cls, u_max) -> AbstractHysteresis:
        """Untrained model behind a Joule cascade's thermal lag, for drives in ``[0, u_max]`` (`smafl fit --model
        cascade-NAME`): the class's default grid unless the class says otherwise."""
        return cls.from_range(0.0, u_max)

    # -- construction --------------------------------------------------------
    @classmethod
    @abc.abstractmethod
    def from_range(cls, u_min, u_max, **options) -> AbstractHysteresis:
        """Untrained model (weights zero) for inputs in ``[u_min, u_max]``."""

    @abc.abstractmethod
    def with_range(self, u_min, u_max) -> AbstractHysteresis:
        """Untrained model of the same structure (grid sizes, options) for inputs in ``[u_min, u_max]``."""

    # -- linear structure ----------------------------------------------------
    @abc.abstractmethod
    def features(self, x, dt=None) -> jnp.ndarray:
        """Design matrix ``(T, p)`` of the linear weights on input record ``x`` (same state rule as `simulate`; ``dt`` ignored)."""

    @abc.abstractmethod
    def linear_weights(self) -> jnp.ndarray:
        """Weights ``(p,)`` in the column order of `features`."""

    @abc.abstractmethod
    def with_linear_weights(self, theta) -> AbstractHysteresis:
        """Copy with the weights taken from ``theta`` (column order of `features`)."""

    @abc.abstractmethod
    def nonnegative_columns(self) -> np.ndarray:
        """Bool mask over `features` columns whose weights must be >= 0."""

    @abc.abstractmethod
    def linear_fields(self) -> tuple[str, ...]:
        """Names of the fields `with_linear_weights` sets (marginalised / profiled together by the sampler)."""

    def weight_scales(self) -> dict[str, float]:
        """Prior scale of each linear field's weights, relative to the output range (the sampler's priors).

        1 (the default) for a weight whose feature column alone can span the output (an EUPI gain);
        a bank of ``n`` relays sharing the output gets ``1 / sqrt(n)`` each, so the bank as a whole
        has the scale of one gain.
        """
        return dict.fromkeys(self.linear_fields(), 1.0)

    @abc.abstractmethod
    def fixed_fields(self, train: Collection[str] = ()) -> tuple[str, ...]:
        """Names of the array fields never trained or sampled; groups of `trainable_groups` named in ``train`` are trained."""

    def nonlinear_priors(self) -> dict[str, tuple[str, float, float]]:
        """The sampler's default priors of trainable fields outside the linear weights: ``{field: (dist, loc, scale)}``.

        ``dist`` names a `smafl_jax.Prior` distribution, in the field's own units.  For the optional
        `trainable_groups` and other nonlinear fields (a fitted initial state) that a fit may train; a field
        left out gets a flat prior.  The linear weights' priors follow from `linear_fields`,
        `nonnegative_columns` and `weight_scales` (`smafl_jax.bayes.default_priors`).  None by default.
        """
        return {}

    # -- state rule ------------------------------------------------------------
    @abc.abstractmethod
    def initial_state(self, x0) -> Any:
        """State before the first sample for a record whose first input is ``x0`` (the ``init`` rule)."""

    @abc.abstractmethod
    def step(self, state, x) -> tuple[Any, jnp.ndarray]:
        """One sample: ``(state, x(k)) -> (state, y(k))`` (pure; the body of the whole-record scan)."""

    # -- evaluation ------------------------------------------------------------
    def simulate(self, u, dt=None) -> jnp.ndarray:
        """Output for input record ``u`` (1-D). ``dt`` is ignored: the model is rate-independent."""
        del dt
        x = jnp.asarray(u, dtype=jnp.float64)
        _, y = jax.lax.scan(lambda state, xk: self.step(state, xk), self.initial_state(x[0]), x)
        return y

    def __call__(self, u, dt=None) -> jnp.ndarray:
        return self.simulate(u, dt)

    def seen(self, x):
        """The input as the model takes it: ``x`` held to ``held`` = [lo, hi] when the model has one (`with_held`; a side
        that is None is open)."""
        x = jnp.asarray(x, dtype=jnp.float64)
        held = getattr(self, "held", None)
        if held is None:
            return x
        x = x if held[0] is None else jnp.maximum(x, held[0])
        return x if held[1] is None else jnp.minimum(x, held[1])

    def with_held(self, lo: float | None, hi: float | None = None) -> AbstractHysteresis:
        """Copy that holds its input to [lo, hi]; a side given as None is open (the model extrapolates there), and
        ``with_held(None)`` holds nothing (the default of a new model).

        Why: outside the range a model was fitted on, its play operators and polynomial extrapolate without a physical
        meaning, and a hysteresis keeps the memory of the excursion.  `smafl_jax.report.fit_record` holds a model that
        sees a measured input directly (temperature, pressure) at its trained range (``hold_input``): on the shared
        NiTi records, predicted run by run from the others, that cut a run whose thermocouple spiked to 220 C from
        18.2 to 3.9 and a run in 0 C water from 9.2 to 1.2 (length units), and changed no run inside the range.  A
        cascade's thermal state is held below only (`smafl_jax.identify._hold`)."""
        if lo is None and hi is None:
            return dataclasses.replace(self, held=None)
        lo, hi = (None if v is None else float(v) for v in (lo, hi))
        if not all(v is None or np.isfinite(v) for v in (lo, hi)) or (lo is not None and hi is not None and not hi > lo):
            raise ValueError(f"held range must be finite with hi > lo, got [{lo}, {hi}]")
        return dataclasses.replace(self, held=(lo, hi))

    def held_lines(self) -> list[str]:
        """The `describe` line of a held input ([] without one)."""
        held = getattr(self, "held", None)
        if held is None:
            return []
        lo, hi = held
        if hi is None:
            return [
                f"input held at or above {lo:.6g}, the low edge of its trained range: below it the model does not extrapolate"
            ]
        if lo is None:
            return [
                f"input held at or below {hi:.6g}, the high edge of its trained range: above it the model does not extrapolate"
            ]
        return [f"input held to its trained range [{lo:.6g}, {hi:.6g}]: outside it the model does not extrapolate"]

    def normalise(self, x):
        """``s = (x - u_ref) / u_span`` of the input as the model takes it (`seen`)."""
        return (self.seen(x) - self.u_ref) / self.u_span

    def denormalise(self, s):
        """Inverse of `normalise`."""
        return jnp.asarray(s, dtype=jnp.float64) * self.u_span + self.u_ref

    def with_init(self, init: str) -> AbstractHysteresis:
        """Copy started by the initial-state rule ``init`` (one of `INITS` that needs no extra parameter)."""
        if init not in self.INITS:
            raise ValueError(f"{type(self).__name__} init must be one of {self.INITS}, got {init!r}")
        return dataclasses.replace(self, init=init)

    def screening_form(self, rule: str) -> AbstractHysteresis:
        """A copy whose output equals that of ``with_init(rule)`` for the start screening to profile.

        A model may return a form whose traced structure is the same for every rule in `RULE_INITS` (the rule held in
        an array, not a static field), so the screening compiles once for all rules; `with_init` turns the winner back.
        """
        return self.with_init(rule)

    def for_record(self, i: int) -> AbstractHysteresis:
        """The model as it starts record ``i`` of a joint fit: the same (its memory rule applies to each record's own
        first input; only a thermal stage holds per-record starts, `JouleThermal.for_record`)."""
        del i
        return self

    def with_method(self, method: str) -> AbstractHysteresis:
        """Copy evaluated by ``method`` (models with parallel-in-time forms override; others have one form)."""
        del method
        return self

    def memory_columns(self, x, fractions) -> tuple[np.ndarray, jnp.ndarray] | None:
        """Design columns of a memory held per operator, for the per-operator search of the state at t = 0
        (`smafl_jax.identify.search_memory`): ``(columns, C)`` with ``columns`` the indices of the operator columns in
        `features` and ``C[k, :, i]`` operator ``i``'s column when it starts ``fractions[k, i]`` of the way from its
        lower to its upper bound at the first input.  None (the default): the class has no such memory."""
        del x, fractions
        return None

    def with_memory_fractions(self, fractions) -> AbstractHysteresis:
        """Copy whose operators start ``fractions`` (one per operator, in (0, 1)) of the way between their bounds
        (the form `memory_columns` searches).  Only for a class whose `memory_columns` is not None."""
        raise NotImplementedError(f"{type(self).__name__} has no per-operator memory")

    # -- as a model: a hysteresis is its own hysteresis part --------------------------
    @property
    def hysteresis(self) -> AbstractHysteresis:
        return self

    def with_hysteresis(self, h: AbstractHysteresis) -> AbstractHysteresis:
        return h

    def hysteresis_input(self, u, dt=None):
        """The signal the hysteresis sees: the input itself."""
        del dt
        return jnp.asarray(u, dtype=jnp.float64)

    def steady_drive(self, u):
        """Hysteresis input once a constant input ``u`` has been held (the input itself; a cascade maps it)."""
        return u

    def plant_parts(self) -> tuple[None, AbstractHysteresis]:
        """``(thermal stage or None, hysteresis)``: the per-sample stages `smafl_jax.control.plant_step` runs (one here)."""
        return None, self

    # -- report -------------------------------------------------------------------
    def describe(self) -> list[str]:
        """The key parameters for a fit report (``report.md``), one line each (markdown, no bullet).

        This default needs only the protocol: weight count, non-zero non-negative weights, normalisation,
        initial-state rule and orientation; a model overrides it with its own quantities.
        """
        w = np.asarray(self.linear_weights(), dtype=float)
        nonneg = np.asarray(self.nonnegative_columns())
        return [
            f"{type(self).__name__}: {w.size} linear weights ({int(np.sum(nonneg & (w > 1e-9)))} of the {int(nonneg.sum())} "
            f"non-negative ones non-zero), u_ref {float(self.u_ref):g}, u_span {float(self.u_span):g}, init {self.init}",
            _orientation_line(self.orientation),
            *self.held_lines(),
        ]


def check_orientation(model: AbstractHysteresis, name: str) -> None:
    """``__check_init__`` part of every class with an ``orientation``: +1 / -1, or 0 with a ``sign`` leaf (its
    `AbstractHysteresis.compile_form`) and only then."""
    formed = model.orientation == 0 and model.sign is not None
    if model.orientation not in (1, -1) and not formed:
        raise ValueError(f"{name} orientation must be +1 or -1, got {model.orientation!r}")
    if model.sign is not None and not formed:
        raise ValueError(f"{name} sign belongs to its compile form (orientation 0), got orientation {model.orientation!r}")


def _orientation_line(orientation) -> str:
    return f"output orientation: {'rises' if orientation > 0 else 'falls'} with contraction"


class AbstractScaledShape(AbstractHysteresis):
    """A hysteresis that is one non-negative ``scale`` on a shape in [0, 1] (`shape`), plus a reversible linear term
    ``gain * s`` and an ``offset``: ``y = o * scale * shape(u) + gain * s + offset`` (`GaussianPreisach`,
    `PhaseFraction`).  The subclass declares the fields ``scale`` (positive), ``gain`` and ``offset``."""

    @abc.abstractmethod
    def shape(self, u) -> jnp.ndarray:
        """The shape per sample, in [0, 1] (one scan)."""

    def linear_fields(self):
        return ("scale", "gain", "offset")

    def features(self, u, dt=None):
        """Design matrix ``(T, 3)``: ``[o * shape, s, 1]`` (the orientation signs the non-negative column only, as in
        every hysteresis model)."""
        del dt
        f = self.shape(u)
        return jnp.stack([self.orientation_sign() * f, self.normalise(u), jnp.ones_like(f)], axis=1)

    def linear_weights(self):
        return jnp.stack([self.scale, self.gain, self.offset])

    def nonnegative_columns(self):
        return np.array([True, False, False])

    def with_linear_weights(self, theta):
        theta = jnp.asarray(theta, dtype=jnp.float64)
        if theta.shape != (3,):
            raise ValueError(f"expected 3 linear weights (scale, gain, offset), got shape {theta.shape}")
        return eqx.tree_at(lambda p: (p.scale, p.gain, p.offset), self, (theta[0], theta[1], theta[2]))

    def read_out(self, shape, x):
        """Output from the shape and the input (one sample in `step`, or a whole record)."""
        return self.orientation_sign() * self.scale * shape + self.gain * self.normalise(x) + self.offset

    def simulate(self, u, dt=None):
        """Output for input record ``u`` (1-D). ``dt`` is ignored: the model is rate-independent."""
        del dt
        u = jnp.asarray(u, dtype=jnp.float64)
        return self.read_out(self.shape(u), u)


def hysteresis_of(model: Any) -> AbstractHysteresis | None:
    """The hysteresis part of ``model`` (the model itself, a cascade's, an extended model's), or None."""
    h = getattr(model, "hysteresis", None)
    return h if isinstance(h, AbstractHysteresis) else None


def thermal_of(model: Any) -> Any:
    """The thermal stage that feeds ``model``'s hysteresis (a cascade's, an extended model's base cascade's), or None.

    The one place that answers "does this model have a thermal lag in front of its hysteresis?", so callers ask the
    model instead of testing its class."""
    return getattr(model, "thermal", None) if hysteresis_of(model) is not None else None


def record_model(model: Any, i: int) -> Any:
    """``model`` as it starts record ``i`` of a joint fit: its ``for_record(i)`` (per-record starts: `Cascade`,
    `JouleThermal`), or the model itself for a class without per-record state (any user model with a ``simulate``)."""
    per_record = getattr(model, "for_record", None)
    return model if per_record is None else per_record(i)


def linear_field_columns(h: AbstractHysteresis) -> dict[str, np.ndarray]:
    """``{linear field: the columns of features its weights multiply}`` (integer arrays, flattened field order)."""
    p = int(np.shape(h.linear_weights())[0])
    index = h.with_linear_weights(jnp.arange(p, dtype=jnp.float64))  # each field then holds its column numbers
    return {field: np.asarray(getattr(index, field), dtype=int).ravel() for field in h.linear_fields()}


def column_weight_scales(h: AbstractHysteresis) -> np.ndarray:
    """`AbstractHysteresis.weight_scales` spread over the columns of ``features`` (``(p,)``)."""
    p = int(np.shape(h.linear_weights())[0])
    index = h.with_linear_weights(jnp.arange(p, dtype=jnp.float64))  # each field then holds its column numbers
    out = np.ones(p)
    linear = set(h.linear_fields())
    for field, scale in h.weight_scales().items():
        if field in linear:  # a scale for a field that is not a linear weight (a non-linear Preisach's gain) has no column
            out[np.asarray(getattr(index, field), dtype=int).ravel()] = scale
    return out


def hysteresis_class(name: str) -> type:
    """Concrete hysteresis class registered as ``name`` in `smafl_jax._choices.HYSTERESIS`."""
    from .._choices import HYSTERESIS

    if name not in HYSTERESIS:
        raise KeyError(f"unknown hysteresis model {name!r}; registered: {sorted(HYSTERESIS)}")
    module, cls = HYSTERESIS[name].split(":")
    return getattr(import_module(f"smafl_jax.{module}"), cls)


def hysteresis_models() -> list[type]:
    """Every registered concrete hysteresis class (tests parametrise over this list)."""
    from .._choices import HYSTERESIS

    return [hysteresis_class(name) for name in HYSTERESIS]
