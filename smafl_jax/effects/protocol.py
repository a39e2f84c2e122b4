"""Effect protocol: what every catalogue effect declares about itself (diffrax-style abstract classes).

An effect is an `equinox.Module` holding its parameters.  Its class declares everything the rest of the
toolkit needs, so that `ExtendedModel` and the diagnosis (`smafl_jax.diagnosis._diagnose`) never switch on effect names:

- ``name`` (catalogue name), ``needs`` (``"thermal"``: a `Cascade` base, ``"time"``: record dynamics,
  ``"load"``: a load column), ``physics`` and ``parameters`` (documentation, and the fields reported);
- ``stage``: where it acts in the cascade, one of `STAGES`, and the stage's method(s), given by the stage's
  abstract base class below (`AbstractInputEffect.transform_input`, `AbstractThermalEffect` hooks, ...).
  `ExtendedModel` applies the stages in `STAGES` order; inside a stage, effects act in catalogue order;
- identification: ``nonlinear(ctx)`` (the parameters searched by the nonlinear optimiser, each with a
  `Transform` to an unconstrained coordinate and a simplex step), ``grid(ctx)`` (starting points),
  ``probes(ctx)`` (weak versions whose output change is the score-test signature), ``held_fields``
  (fields never trained) and, for effects with linear parameters, the design columns or design map of
  the stage;
- ``synthesise(rng, ctx)`` with its ``synthetic`` description: a random effect of a clearly visible
  strength for synthetic records (`smafl_jax.diagnosis._diagnose.synthetic_effect_record`).

``ctx`` is a plain dict describing the training data (`smafl_jax.diagnosis._diagnose._context`): ``dt``,
``duration`` (longest training stretch, s), ``y_lo``, ``y_mid``, ``y_range`` and, with a load column,
``load_ref``, ``load_scale``.

Registry: `register_effect` (a class decorator) adds a class to `EFFECTS` (catalogue name -> class,
in catalogue order) and registers it for JSON saving; adding an effect is one decorated class.
"""

from __future__ import annotations

import abc
import dataclasses
from typing import Any, ClassVar, NamedTuple

import equinox as eqx
import numpy as np

from .. import _config  # noqa: F401
from .._io import register_model

__all__ = [
    "STAGES",
    "EFFECTS",
    "AbstractEffect",
    "Effect",
    "AbstractInputEffect",
    "AbstractThermalEffect",
    "AbstractWarpEffect",
    "AbstractThresholdEffect",
    "AbstractFeatureEffect",
    "AbstractLinearEffect",
    "AbstractOutputEffect",
    "Transform",
    "Log",
    "Linear",
    "Tanh",
    "LogBox",
    "Nonlinear",
    "OutputLink",
    "register_effect",
    "effect_rank",
]

#: Stages of the cascade, in the order `ExtendedModel` applies them:
#: ``input`` (the measured drive: delay, lag), ``thermal`` (the Joule thermal model), ``hysteresis_input``
#: (the signal the hysteresis sees: warps), ``hysteresis`` (the play thresholds), ``features`` (the design
#: matrix of the hysteresis weights), ``linear`` (output terms linear in an effect parameter, profiled with
#: the weights) and ``output`` (maps of the output).
STAGES = ("input", "thermal", "hysteresis_input", "hysteresis", "features", "linear", "output")

#: Catalogue name -> effect class, in catalogue (and within-stage application) order.
EFFECTS: dict[str, type] = {}


# -- nonlinear parameter transforms (numpy: the diagnosis' Nelder-Mead works on phi) -------------------------


class Transform(abc.ABC):
    """Map between a parameter value and the unconstrained coordinate ``phi`` a simplex search moves."""

    @abc.abstractmethod
    def to_phi(self, v: float) -> float: ...

    @abc.abstractmethod
    def from_phi(self, p: float) -> float: ...

    def at_bound(self, p: float) -> bool:
        """Whether ``phi`` puts the parameter at an end of its range (within `BOUND_FRACTION` of it), where the map
        is flat and a simplex stalls: False for an unbounded transform."""
        return False


#: Fraction of a bounded transform's range counted as "at its bound" (`Transform.at_bound`).
BOUND_FRACTION = 0.01


@dataclasses.dataclass(frozen=True)
class Log(Transform):
    """Positive parameter: ``phi = log v``."""

    def to_phi(self, v):
        return np.log(max(v, 1e-12))

    def from_phi(self, p):
        return float(np.exp(np.clip(p, -30, 30)))


@dataclasses.dataclass(frozen=True)
class Linear(Transform):
    """Signed parameter: ``phi = v``."""

    def to_phi(self, v):
        return v

    def from_phi(self, p):
        return float(p)


@dataclasses.dataclass(frozen=True)
class Tanh(Transform):
    """Parameter bounded by ``|v| <= bound``: ``v = bound tanh(phi)``."""

    bound: float = 1.0

    def to_phi(self, v):
        return float(np.arctanh(np.clip(v / self.bound, -1.0 + 1e-9, 1.0 - 1e-9)))

    def from_phi(self, p):
        return float(self.bound * np.tanh(p))

    def at_bound(self, p):
        return bool(abs(np.tanh(p)) > 1.0 - 2.0 * BOUND_FRACTION)  # |v| in the outer 1 % of [-bound, bound]


@dataclasses.dataclass(frozen=True)
class LogBox(Transform):
    """Positive parameter inside ``[lo, hi]``: ``log v`` is a logistic function of ``phi``."""

    lo: float
    hi: float

    def _logs(self):
        return np.log((self.lo, self.hi))

    def to_phi(self, v):
        llo, lhi = self._logs()
        f = np.clip((np.log(max(v, 1e-300)) - llo) / (lhi - llo), 1e-6, 1.0 - 1e-6)
        return float(np.log(f / (1.0 - f)))

    def from_phi(self, p):
        llo, lhi = self._logs()
        return float(np.exp(llo + (lhi - llo) / (1.0 + np.exp(-np.clip(p, -50, 50)))))

    def at_bound(self, p):
        f = 1.0 / (1.0 + np.exp(-np.clip(p, -50, 50)))  # position of log v in [log lo, log hi]
        return bool(min(f, 1.0 - f) < BOUND_FRACTION)


class Nonlinear(NamedTuple):
    """A nonlinear parameter: the effect's ``field``, its `Transform` and the initial simplex step in phi."""

    field: str
    transform: Transform
    step: float


class OutputLink(NamedTuple):
    """A nonlinear output map for the profiled least squares (numpy): ``y = forward(z)`` with its inverse
    (a starting target) and ``slope = d forward / dz`` (Gauss-Newton)."""

    forward: Any
    inverse: Any
    slope: Any


# -- the protocol ---------------------------------------------------------------------------------------------


class AbstractEffect(eqx.Module):
    """A physical effect added to the base cascade (see module docstring). Subclass a stage class below."""

    name: ClassVar[str] = ""
    needs: ClassVar[tuple] = ()  # "thermal", "time", "load"
    stage: ClassVar[str] = ""
    physics: ClassVar[str] = ""
    parameters: ClassVar[dict] = {}
    #: How `synthesise` draws the effect's strength (documentation of synthetic records).
    synthetic: ClassVar[str] = ""
    #: ``simulate(u, dt) == features(u, dt) @ weights`` still holds with the effect (no load given).
    linear_in_weights: ClassVar[bool] = True
    #: The effect scales the play thresholds per sample: the hysteresis must have ``scalable_thresholds``.
    scales_thresholds: ClassVar[bool] = False
    #: Groups of effects whose residual signatures one record often cannot tell apart (issue 13 names them: the thermal
    #: family; creep and slow drift; delay, lag and rate dependence; static maps of the input or output).  When effects
    #: that explain a residual equally well share no group, the diagnosis names none of them (`diagnosis.lookalike_groups`):
    #: a residual that unrelated effects explain alike is structure the base model misses, not the signature of one.
    lookalikes: ClassVar[tuple[str, ...]] = ()

    @classmethod
    @abc.abstractmethod
    def nonlinear(cls, ctx: dict) -> tuple[Nonlinear, ...]:
        """The nonlinear (searched) parameters, in search order; linear ones are profiled and not listed."""

    @classmethod
    @abc.abstractmethod
    def grid(cls, ctx: dict) -> list[AbstractEffect]:
        """Starting points of the fit (the best one starts the nonlinear search)."""

    @classmethod
    @abc.abstractmethod
    def probes(cls, ctx: dict) -> list[AbstractEffect]:
        """Weak versions of the effect (several cover its nuisance parameters) for the score test."""

    @classmethod
    @abc.abstractmethod
    def synthesise(cls, rng: np.random.Generator, ctx: dict) -> tuple[AbstractEffect, dict]:
        """A random effect of the strength described by ``synthetic`` and the extra record columns it needs.

        ``ctx``: ``dt``, ``n`` (samples), ``y_lo``, ``y_hi`` (range of the output without the effect) and
        ``sign`` (a random +-1 drawn for every record, used by signed effects).
        """

    def held_fields(self, *, load: bool = True) -> tuple[str, ...]:
        """Array fields never trained (references, scales); ``load=False``: no load signal is given."""
        del load
        return ()


#: Old name of the base class (kept for imports).
Effect = AbstractEffect


class AbstractInputEffect(AbstractEffect):
    """Acts on the measured drive before anything else (transport delay, sensor lag)."""

    stage: ClassVar[str] = "input"

    @abc.abstractmethod
    def transform_input(self, x, dt):
        """The drive after the effect (``x`` 1-D, ``dt`` the sample time)."""


class AbstractThermalEffect(AbstractEffect):
    """Acts inside the thermal model, written on the state ``q`` in V^2 units (see `smafl_jax.effects.extended`).

    One step of the locally linear thermal model is

        heat = heating(U^2, q),  c = product of loss(q),  target = heat / c + sum of ambient(t),
        rate = rate(k1 c, target, q),  q <- a q + (1 - a) target,  a = exp(-rate dt)

    and each hook defaults to no change.  With a bare hysteresis base (no thermal model) an effect that does
    not need ``"thermal"`` acts through `without_thermal` instead.
    """

    stage: ClassVar[str] = "thermal"

    def heating(self, heat, q, q_ref):
        return heat

    def loss(self, q, q_ref):
        """Multiplicative loss coefficient ``c(q)`` (None: 1)."""
        return None

    def rate(self, rate, target, q, q_ref):
        """Thermal rate of this step (``target`` the state it relaxes to; default unchanged)."""
        return rate

    def ambient(self, t, q_ref):
        """Additive ambient term of the target (None: 0); ``t`` the sample times from 0."""
        return None

    def without_thermal(self, x, t, hysteresis):
        """The hysteresis input when the base has no thermal model (only for effects not needing ``"thermal"``)."""
        raise NotImplementedError(f"effect {self.name!r} acts on the thermal model only")


class AbstractWarpEffect(AbstractEffect):
    """Maps the signal the hysteresis sees (after the thermal model) before the play operators."""

    stage: ClassVar[str] = "hysteresis_input"

    @abc.abstractmethod
    def warp(self, x, hysteresis):
        """The warped hysteresis input (``hysteresis`` gives the normalisation)."""


class AbstractThresholdEffect(AbstractEffect):
    """Scales the play thresholds per sample (needs a hysteresis with ``scalable_thresholds``)."""

    stage: ClassVar[str] = "hysteresis"
    scales_thresholds: ClassVar[bool] = True

    @abc.abstractmethod
    def threshold_scale(self, x, dt, hysteresis):
        """Per-sample threshold factor ``(T,)`` for hysteresis input ``x``."""


class AbstractFeatureEffect(AbstractEffect):
    """Acts on the design matrix of the hysteresis weights (so the output stays linear in them)."""

    stage: ClassVar[str] = "features"

    @abc.abstractmethod
    def filter_features(self, F, dt):
        """The features ``(T, p)`` after the effect."""


class AbstractLinearEffect(AbstractEffect):
    """Adds output terms ``sum_f field_f * column_f`` linear in its fields (profiled beside the weights)."""

    stage: ClassVar[str] = "linear"
    linear_in_weights: ClassVar[bool] = False
    #: The fields that enter the output linearly (one column each).
    linear_fields: ClassVar[tuple] = ()

    @abc.abstractmethod
    def columns(self, model, u, dt) -> dict:
        """``{field: column (T,)}`` for each of ``linear_fields``: the output change per unit of the field for
        drive ``u`` (``model`` the `ExtendedModel`, for its hysteresis input)."""


class AbstractOutputEffect(AbstractEffect):
    """Maps the output of the hysteresis (and linear terms) to the measured output."""

    stage: ClassVar[str] = "output"

    @abc.abstractmethod
    def output(self, y, dt, load):
        """The output after the effect (``load`` the load signal or None)."""

    def profile_design(self, A, t, load):
        """Design of the profiled least squares after the effect: ``(A, added linear fields)`` (numpy; ``t`` and
        ``load`` the scored samples' times from the segment start and loads, or None).  Default: unchanged."""
        del t, load
        return A, ()

    def profile_link(self) -> OutputLink | None:
        """Nonlinear map of ``A @ theta`` for the profiled least squares (None: linear)."""
        return None


def register_effect(cls):
    """Class decorator: add a concrete effect class to the catalogue `EFFECTS` and make it loadable from JSON."""
    if not cls.name or cls.stage not in STAGES:
        raise ValueError(f"effect class {cls.__name__} needs a name and a stage in {STAGES}")
    if cls.name in EFFECTS and EFFECTS[cls.name] is not cls:
        raise ValueError(f"effect name {cls.name!r} is already registered by {EFFECTS[cls.name].__name__}")
    EFFECTS[cls.name] = register_model(cls)
    return cls


def effect_rank(name: str) -> int:
    """Catalogue position of ``name`` (unregistered names after every registered one)."""
    names = list(EFFECTS)
    return names.index(name) if name in names else len(names)
