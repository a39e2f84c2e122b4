"""Catalogue of physical effects that extend the base cascade (issue 6).

`ExtendedModel(base, effects)` composes a base model (a `Cascade`, or a bare
hysteresis model, `EUPI` or `Preisach`, for rate-free records and non-voltage
inputs) with effect modules.  It reaches the hysteresis only through the
`smafl_jax._hysteresis.AbstractHysteresis` protocol (``features`` on a
transformed input, ``linear_weights``); ``rate_dependence`` scales thresholds
per sample and so needs a model with ``scalable_thresholds`` (the EUPI).  Each
effect is an `equinox.Module` registered for JSON, so an extended model saves,
loads and runs with ``smafl simulate`` like any other model.  The pipeline is

    u --delay--> --sensor_lag--> x --thermal (+ resistance_tc, asymmetric_cooling,
    nonlinear_cooling, ambient_drift)--> u_eff --input_warp--> --EUPI
      (+ rate_dependence)--> H --creep--> (+ strain_accumulation) --output_saturation-->
      --load_dependence--> y

Thermal effects are written on the thermal state in *voltage-squared units*
``q = theta k1 / k2`` (the steady-state value of ``q`` is the applied ``U^2``),
which removes the unidentifiable ``k2`` and gives every effect parameter a
scale: ``q_ref = u_span^2`` of the EUPI.  With ``q`` the base model is

    dq/dt = k1 (U^2 - q),    u_eff = sqrt(q)

and the extended thermal model is

    dq/dt = k1 rho(dir) [ U^2 h(q) - q c(q) + q_amb(t) ]

with ``h = 1 / (1 + beta q / q_ref)`` (resistance_tc), ``c = 1 + gamma q / q_ref``
(nonlinear_cooling), ``rho = exp(log_ratio)`` while cooling (asymmetric_cooling)
and ``q_amb = drift q_ref t / 1000 s`` (ambient_drift).  It is integrated with
the exact first-order hold of the base model, the nonlinear coefficients frozen
at the previous state (a locally linear step that stays stable for any dt and
reduces to the base model exactly when the effects vanish).

For a bare-EUPI base (temperature input, quasi-static voltage) the thermal
effects do not apply; ``ambient_drift`` then shifts the input by
``drift u_span t / 1000 s``.

``load_dependence`` needs a load signal: ``simulate(u, dt, load=L)``; without
one (``smafl simulate``) the model predicts at its reference load.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp

from . import _config  # noqa: F401
from ._cascade import Cascade
from ._constraints import positive
from ._hysteresis import AbstractHysteresis, hysteresis_of
from ._io import register_model
from ._thermal import _safe_sqrt

__all__ = [
    "ExtendedModel",
    "EFFECTS",
    "EFFECT_NAMES",
    "Delay",
    "SensorLag",
    "AmbientDrift",
    "ResistanceTC",
    "AsymmetricCooling",
    "NonlinearCooling",
    "RateDependence",
    "Creep",
    "OutputSaturation",
    "InputWarp",
    "LoadDependence",
    "StrainAccumulation",
    "effect_names",
    "warp_input",
    "fractional_delay",
]

#: Time scale of drift parameters (s): ``drift`` is the change per 1000 s.
DRIFT_TIME = 1000.0
#: Rate scale (s): rate_dependence uses ``|ds/dt| * RATE_TIME`` (s normalised input).
RATE_TIME = 100.0
#: Time scale of strain_accumulation (s): ``c`` is the output change per 1000 s at full drive.
ACCUMULATION_TIME = 1000.0


class Effect(eqx.Module):
    """Base class: ``name`` (catalogue name), ``needs`` (what the base must have)."""

    name: ClassVar[str] = ""
    needs: ClassVar[tuple] = ()  # "thermal", "time", "load"
    physics: ClassVar[str] = ""
    parameters: ClassVar[dict] = {}


@register_model
class Delay(Effect):
    """Transport delay of the drive (dead time of the driver, sensor or heat conduction)."""

    name: ClassVar[str] = "delay"
    needs: ClassVar[tuple] = ("time",)
    physics: ClassVar[str] = (
        "The output responds to the input tau seconds late (amplifier/DAQ latency, heat conduction from the SMA wire into the polymer, sensor filtering)."
    )
    parameters: ClassVar[dict] = {"tau": "delay in seconds (> 0), fractional delays by linear interpolation"}
    tau: jnp.ndarray = positive()


@register_model
class SensorLag(Effect):
    """First-order lag between the measured input and what the hysteresis sees (smoothing, unlike `Delay`)."""

    name: ClassVar[str] = "sensor_lag"
    needs: ClassVar[tuple] = ("time",)
    physics: ClassVar[str] = (
        "The transforming material follows the measured input through a first-order lag: heat conduction from the bath "
        "or the thermocouple into the wire, or the sensor's own response time. The hysteresis sees x'(k) = x'(k-1) + "
        "(1 - exp(-dt/tau)) (x(k) - x'(k-1)), x'(0) = x(0) (exact for a zero-order-hold input); unlike a transport delay "
        "it smooths steps."
    )
    parameters: ClassVar[dict] = {"tau": "lag time constant in seconds (> 0)"}
    tau: jnp.ndarray = positive()


@register_model
class AmbientDrift(Effect):
    """Slow drift of the ambient (thermal equilibrium) during the record."""

    name: ClassVar[str] = "ambient_drift"
    needs: ClassVar[tuple] = ("time",)
    physics: ClassVar[str] = (
        "The ambient temperature (or the rest temperature of the actuator) drifts linearly during the record, shifting the thermal state the hysteresis sees."
    )
    parameters: ClassVar[dict] = {
        "drift": "change of the thermal state per 1000 s in units of q_ref = u_span^2 (cascade) or of the input span (EUPI base); signed"
    }
    drift: jnp.ndarray


@register_model
class ResistanceTC(Effect):
    """Temperature coefficient of the wire resistance: Joule heating falls as the wire warms."""

    name: ClassVar[str] = "resistance_tc"
    needs: ClassVar[tuple] = ("thermal",)
    physics: ClassVar[str] = (
        "R = R0 (1 + beta q / q_ref): at constant voltage the heating power U^2/R falls as the wire warms, so hot states are reached more slowly and saturate lower."
    )
    parameters: ClassVar[dict] = {"beta": "relative resistance increase at q = q_ref (> 0)"}
    beta: jnp.ndarray = positive()


@register_model
class AsymmetricCooling(Effect):
    """Different thermal time constants for heating and cooling."""

    name: ClassVar[str] = "asymmetric_cooling"
    needs: ClassVar[tuple] = ("thermal",)
    physics: ClassVar[str] = (
        "Cooling (heat loss to a still environment, latent heat of the reverse transformation) runs at a different rate than Joule heating: the rate is k1 exp(log_ratio) while the state falls."
    )
    parameters: ClassVar[dict] = {"log_ratio": "log of cooling rate / heating rate (signed)"}
    log_ratio: jnp.ndarray


@register_model
class NonlinearCooling(Effect):
    """Convective/radiative cooling that grows faster than linearly with temperature."""

    name: ClassVar[str] = "nonlinear_cooling"
    needs: ClassVar[tuple] = ("thermal",)
    physics: ClassVar[str] = (
        "Heat loss k1 q (1 + gamma q / q_ref): natural convection and radiation make hot states cool faster (and saturate lower) than Newton's law."
    )
    parameters: ClassVar[dict] = {"gamma": "relative extra loss at q = q_ref (> 0)"}
    gamma: jnp.ndarray = positive()


@register_model
class RateDependence(Effect):
    """Rate-dependent hysteresis: loop width grows with the input rate."""

    name: ClassVar[str] = "rate_dependence"
    needs: ClassVar[tuple] = ("time",)
    physics: ClassVar[str] = (
        "Play thresholds widen with the rate of the hysteresis input, r(k) = r (1 + c |ds/dt| 100 s) (viscous friction in the polymer, rate-dependent phase transformation)."
    )
    parameters: ClassVar[dict] = {"c": "threshold widening per unit normalised rate (per 100 s) (> 0)"}
    c: jnp.ndarray = positive()


@register_model
class Creep(Effect):
    """Slow viscoelastic relaxation (creep) of the polymer; a bounded fraction of the output relaxes."""

    name: ClassVar[str] = "creep"
    needs: ClassVar[tuple] = ("time",)
    physics: ClassVar[str] = (
        "A fraction g of the output follows the hysteresis output H through a slow first-order lag L (time constant tau, "
        "seconds to minutes): y = (1 - g) H + g L[H]. After a step the output keeps relaxing while the input is held: "
        "towards the step (g > 0, creep) or back from an overshoot (g < 0, recovery). A relaxation is bounded: |g| <= 1 "
        "(at most the whole step creeps or overshoots) and tau lies between a few samples and the record length (a longer "
        "tau cannot be told from a ramp, which is ambient_drift); the diagnosis fits within these bounds."
    )
    parameters: ClassVar[dict] = {
        "g": "fraction of the output that creeps, signed, |g| <= G_MAX = 1",
        "tau": "creep time constant in seconds, fitted within [TAU_MIN_SAMPLES dt, record length]",
    }
    #: Bounds used when fitting (models saved with values outside them still load and run unchanged).
    G_MAX: ClassVar[float] = 1.0
    TAU_MIN_SAMPLES: ClassVar[float] = 2.0
    g: jnp.ndarray
    tau: jnp.ndarray = positive()

    @classmethod
    def tau_bounds(cls, dt, duration):
        """Fitting range of ``tau`` (s): a few samples up to the (training) record length."""
        lo = cls.TAU_MIN_SAMPLES * float(dt)
        return lo, max(float(duration), 2.0 * lo)


@register_model
class OutputSaturation(Effect):
    """Output saturation: steep sigmoidal SMA transformation between two stroke limits."""

    name: ClassVar[str] = "output_saturation"
    needs: ClassVar[tuple] = ()
    physics: ClassVar[str] = (
        "The stroke is bounded by the completed martensite/austenite transformation: y = m + w tanh((H - m) / w), a monotone sigmoid between m - w and m + w that tends to the identity as w grows."
    )
    parameters: ClassVar[dict] = {
        "m": "centre of the saturation map (output units)",
        "w": "half-width: the output stays within m +- w (> 0)",
    }
    m: jnp.ndarray
    w: jnp.ndarray = positive()


@register_model
class InputWarp(Effect):
    """Transformation warp: the hysteresis acts on a sigmoidal (CDF-like) function of the input."""

    name: ClassVar[str] = "input_warp"
    needs: ClassVar[tuple] = ()
    physics: ClassVar[str] = (
        "The martensite/austenite transformation of an SMA runs over a narrow temperature band, and the quasi-static "
        "wire temperature follows the voltage: the phase fraction is a steep sigmoid of the drive. The play operators "
        "act on the warped input s' = (S((s - c)/b) - S(-c/b)) / (S((1 - c)/b) - S(-c/b)), S the logistic CDF and s "
        "the normalised input, which keeps the input range and puts the threshold grid where the transformation "
        "happens; it tends to the identity as b grows."
    )
    parameters: ClassVar[dict] = {
        "c": "centre of the transformation band (normalised input, fraction of u_span above u_ref)",
        "b": "width of the band (normalised input) (> 0)",
    }
    c: jnp.ndarray
    b: jnp.ndarray = positive()


def warp_input(s, c, b):
    """Monotone logistic warp of the normalised input that maps 0 -> 0 and 1 -> 1 (see `InputWarp`)."""
    lo, hi = jax.nn.sigmoid(-c / b), jax.nn.sigmoid((1.0 - c) / b)
    return (jax.nn.sigmoid((s - c) / b) - lo) / (hi - lo)


@register_model
class LoadDependence(Effect):
    """Stroke and offset change with the mechanical load (needs a load column)."""

    name: ClassVar[str] = "load_dependence"
    needs: ClassVar[tuple] = ("load",)
    physics: ClassVar[str] = (
        "A heavier load stretches the actuator (offset b) and changes the recoverable stroke (gain a): y = H (1 + a l) + b l with l = (L - load_ref) / load_scale."
    )
    parameters: ClassVar[dict] = {
        "a": "relative stroke change per load_scale (signed)",
        "b": "offset per load_scale (signed)",
        "load_ref": "reference load (fixed)",
        "load_scale": "load scale (fixed)",
    }
    a: jnp.ndarray
    b: jnp.ndarray
    load_ref: jnp.ndarray
    load_scale: jnp.ndarray


@register_model
class StrainAccumulation(Effect):
    """Strain that accumulates while the wire is driven (hot/transformed) and stays (permanent, one parameter ``c``)."""

    name: ClassVar[str] = "strain_accumulation"
    needs: ClassVar[tuple] = ("time",)
    physics: ClassVar[str] = (
        "While the wire is hot (transformed, carrying the bias load) strain accumulates monotonically and stays after "
        "cooling: transformation-induced plasticity, functional fatigue, ratcheting of the wire-spring system. Drive "
        "phi = clip(s - s(0), 0, 1) (s the normalised hysteresis input, s(0) its rest level at the record start), "
        "accumulated strain D(t) = -int_0^t phi dt / 1000 s, output y = H + c D(t). c = 0 is the base model. c enters "
        "linearly (profiled with the EUPI gains), so the effect adds no nonlinear parameter. (A recoverable fraction was "
        "tried and dropped: every fit scored on held-out water-step data put the permanent fraction on its bound 1.)"
    )
    parameters: ClassVar[dict] = {
        "c": "output change per 1000 s at full drive (phi = 1), output units, signed (c > 0: the output falls while hot)"
    }
    c: jnp.ndarray


EFFECTS = {
    cls.name: cls
    for cls in (
        Delay,
        SensorLag,
        AmbientDrift,
        ResistanceTC,
        AsymmetricCooling,
        NonlinearCooling,
        InputWarp,
        RateDependence,
        Creep,
        OutputSaturation,
        LoadDependence,
        StrainAccumulation,
    )
}
EFFECT_NAMES = tuple(EFFECTS)


def effect_names():
    """Catalogue names in pipeline order."""
    return EFFECT_NAMES


def fractional_delay(x, delay_samples):
    """``x(k - d)`` with linear interpolation for fractional ``d >= 0``; before the start, ``x(0)``."""
    n = x.shape[0]
    pos = jnp.clip(jnp.arange(n, dtype=jnp.float64) - delay_samples, 0.0, n - 1.0)
    i0 = jnp.floor(pos)
    frac = pos - i0
    i0 = i0.astype(jnp.int32)
    i1 = jnp.minimum(i0 + 1, n - 1)
    return x[i0] * (1.0 - frac) + x[i1] * frac


def _lowpass(x, dt, tau):
    """Exact first-order lag of a ZOH signal, state starting at ``x(0)`` (columns filtered independently)."""
    a = jnp.exp(-dt / tau)

    def step(z, xk):
        z = a * z + (1.0 - a) * xk
        return z, z

    _, z = jax.lax.scan(step, x[0], x)
    return z


@register_model
class ExtendedModel(eqx.Module):
    """Base model (`Cascade` or a hysteresis model) composed with catalogue effects; fitted jointly."""

    base: eqx.Module
    effects: tuple = ()

    def __check_init__(self):
        if isinstance(self.base, ExtendedModel) or hysteresis_of(self.base) is None:
            raise ValueError(
                f"ExtendedModel base must be a Cascade or a hysteresis model (EUPI, Preisach), got {type(self.base).__name__}"
            )
        names = [getattr(e, "name", None) for e in self.effects]
        for e, n in zip(self.effects, names):
            if n not in EFFECTS or not isinstance(e, EFFECTS[n]):
                raise ValueError(f"unknown effect {type(e).__name__}; catalogue: {list(EFFECTS)}")
        if len(set(names)) != len(names):
            raise ValueError(f"each effect may appear once, got {names}")
        for e in self.effects:
            if "thermal" in e.needs and not isinstance(self.base, Cascade):
                raise ValueError(f"effect {e.name!r} acts on the thermal model and needs a Cascade base")
            if e.name == "rate_dependence" and not self.hysteresis.scalable_thresholds:
                raise ValueError(
                    f"effect 'rate_dependence' scales play thresholds per sample; {type(self.hysteresis).__name__} has none"
                )

    # -- structure -------------------------------------------------------
    @property
    def hysteresis(self) -> AbstractHysteresis:
        return self.base.hysteresis

    @property
    def thermal(self):
        """The base cascade's thermal model (AttributeError for a bare hysteresis base)."""
        return self.base.thermal

    @property
    def linear_in_weights(self) -> bool:
        """True when ``simulate(u, dt) == features(u, dt) @ hysteresis.linear_weights()`` (no load given):
        no output saturation and no strain accumulation."""
        return self.get("output_saturation") is None and self.get("strain_accumulation") is None

    @property
    def effect_names(self):
        return [e.name for e in self.effects]

    def get(self, name):
        for e in self.effects:
            if e.name == name:
                return e
        return None

    def with_hysteresis(self, h):
        """Copy with the hysteresis part replaced."""
        return eqx.tree_at(lambda m: m.base, self, self.base.with_hysteresis(h))

    def trainable_spec(self, *, load: bool = True):
        """Bool PyTree: thermal k1, hysteresis weights and effect parameters train; grids, k2 and load references stay.

        ``load=False`` (no load signal, e.g. `smafl_jax.fit` or sampling on a record): the load effect then
        does nothing, so its gains are held too.
        """
        spec = jax.tree_util.tree_map(eqx.is_inexact_array, self)
        fixed = self.hysteresis.fixed_fields()
        spec = eqx.tree_at(lambda s: [getattr(s.hysteresis, f) for f in fixed], spec, [False] * len(fixed))
        if isinstance(self.base, Cascade):
            spec = eqx.tree_at(lambda s: s.base.thermal.k2, spec, False)
        for i, e in enumerate(self.effects):
            if e.name == "load_dependence":
                held = ("load_ref", "load_scale") if load else ("a", "b", "load_ref", "load_scale")
                spec = eqx.tree_at(lambda s: [getattr(s.effects[i], f) for f in held], spec, [False] * len(held))
        return spec

    # -- pipeline --------------------------------------------------------
    def _q_ref(self):
        h = self.hysteresis
        return (h.u_span + h.u_ref) ** 2

    def _thermal(self, x, dt):
        """Thermal state in V^2 units ``q`` for drive ``x`` (see module docstring)."""
        th = self.base.thermal
        k1 = th.k1
        qref = self._q_ref()
        res, asym, nlc, amb = (self.get(n) for n in ("resistance_tc", "asymmetric_cooling", "nonlinear_cooling", "ambient_drift"))
        n = x.shape[0]
        t = jnp.arange(n, dtype=jnp.float64) * dt
        q_amb = amb.drift * qref * t / DRIFT_TIME if amb is not None else jnp.zeros(n)
        # q = theta k1/k2, so every init rule of JouleThermal maps over (steady: x0^2, given: u0^2, ambient: 0)
        q0 = th.initial_state(x[0]) * (th.k1 / th.k2)
        beta = res.beta / qref if res is not None else None
        gamma = nlc.gamma / qref if nlc is not None else None
        rho = jnp.exp(asym.log_ratio) if asym is not None else None

        def step(q, xs):
            xk, qa = xs
            heat = xk * xk
            if beta is not None:
                heat = heat / (1.0 + beta * jnp.maximum(q, 0.0))
            c = 1.0 + gamma * jnp.maximum(q, 0.0) if gamma is not None else 1.0
            target = heat / c + qa
            rate = k1 * c
            if rho is not None:
                rate = jnp.where(target < q, rate * rho, rate)
            a = jnp.exp(-rate * dt)
            q = a * q + (1.0 - a) * target
            return q, q

        _, q = jax.lax.scan(step, q0, (x, q_amb))
        return q

    def hysteresis_input(self, u, dt):
        """Signal the hysteresis sees (after delay, sensor lag, thermal model and drift)."""
        u = jnp.asarray(u, dtype=jnp.float64)
        dt = jnp.asarray(1.0 if dt is None else dt, dtype=jnp.float64)
        d = self.get("delay")
        x = fractional_delay(u, d.tau / dt) if d is not None else u
        lag = self.get("sensor_lag")
        if lag is not None:
            x = _lowpass(x, dt, lag.tau)
        if isinstance(self.base, Cascade):
            q = self._thermal(x, dt)
            return q if self.base.sees == "heat" else _safe_sqrt(q)
        amb = self.get("ambient_drift")
        if amb is not None:
            t = jnp.arange(x.shape[0], dtype=jnp.float64) * dt
            x = x + amb.drift * self.hysteresis.u_span * t / DRIFT_TIME
        return x

    def states(self, u, dt):
        """Internal signals: ``x`` (hysteresis input), ``q`` (thermal state, V^2, cascade only), ``y``."""
        x = self.hysteresis_input(u, dt)
        out = {"x": x, "y": self.simulate(u, dt)}
        if isinstance(self.base, Cascade):
            out["q"] = x * x
        return out

    def features(self, u, dt):
        """Design matrix of the hysteresis weights after input warp, rate dependence and creep (linear in the weights)."""
        dt = jnp.asarray(1.0 if dt is None else dt, dtype=jnp.float64)
        h = self.hysteresis
        x = self.hysteresis_input(u, dt)
        iw = self.get("input_warp")
        if iw is not None:
            x = h.denormalise(warp_input(h.normalise(x), iw.c, iw.b))
        rd = self.get("rate_dependence")
        if rd is None:
            F = h.features(x)
        else:
            s = h.normalise(x)
            rate = jnp.abs(jnp.diff(s, prepend=s[:1])) / dt * RATE_TIME
            F = h.features(x, threshold_scale=1.0 + rd.c * rate)
        cr = self.get("creep")
        if cr is not None:
            F = F + cr.g * (_lowpass(F, dt, cr.tau) - F)
        return F

    def accumulation_column(self, u, dt):
        """Output change per unit ``c`` of `StrainAccumulation`: the accumulated strain ``D(t)`` (see there)."""
        dt = jnp.asarray(1.0 if dt is None else dt, dtype=jnp.float64)
        s = self.hysteresis.normalise(self.hysteresis_input(u, dt))
        phi = jnp.clip(s - s[0], 0.0, 1.0)
        # a plain integral (rectangle rule; phi(0) = 0, so D(0) = 0): a cumsum, no recurrence
        return -jnp.cumsum(phi) * dt / ACCUMULATION_TIME

    def output_map(self, h, load=None):
        """Output-side effects (saturation, load) applied to the linear output ``h``."""
        sat = self.get("output_saturation")
        y = h if sat is None else sat.m + sat.w * jnp.tanh((h - sat.m) / sat.w)
        ld = self.get("load_dependence")
        if ld is not None and load is not None:
            l_ = (jnp.asarray(load, dtype=jnp.float64) - ld.load_ref) / ld.load_scale
            y = y * (1.0 + ld.a * l_) + ld.b * l_
        return y

    def simulate(self, u, dt, load=None):
        """Output for drive ``u`` sampled every ``dt`` s (``load``: optional load signal)."""
        h = self.features(u, dt) @ self.hysteresis.linear_weights()
        sa = self.get("strain_accumulation")
        if sa is not None:
            h = h + sa.c * self.accumulation_column(u, dt)
        return self.output_map(h, load)


class LoadBound(eqx.Module):
    """An `ExtendedModel` with its load signal attached, so generic fitting sees ``simulate(u, dt)``."""

    model: ExtendedModel
    load: jnp.ndarray

    def simulate(self, u, dt):
        return self.model.simulate(u, dt, load=self.load)
