"""The catalogue of physical effects (issue 6), one self-contained class each (protocol: `effects.protocol`).

Classes are registered in catalogue order, which is also the order of effects within a stage.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import _config  # noqa: F401
from ..models._constraints import as_float_array, positive
from .protocol import (
    AbstractFeatureEffect,
    AbstractInputEffect,
    AbstractLinearEffect,
    AbstractOutputEffect,
    AbstractThermalEffect,
    AbstractThresholdEffect,
    AbstractWarpEffect,
    Linear,
    Log,
    LogBox,
    Nonlinear,
    OutputLink,
    Tanh,
    register_effect,
)

__all__ = [
    "DRIFT_TIME",
    "RATE_TIME",
    "ACCUMULATION_TIME",
    "Delay",
    "SensorLag",
    "AmbientDrift",
    "ResistanceTC",
    "AsymmetricCooling",
    "NonlinearCooling",
    "InputWarp",
    "RateDependence",
    "Creep",
    "OutputSaturation",
    "LoadDependence",
    "StrainAccumulation",
    "warp_input",
    "fractional_delay",
]

#: Time scale of drift parameters (s): ``drift`` is the change per 1000 s.
DRIFT_TIME = 1000.0
#: Rate scale (s): rate_dependence uses ``|ds/dt| * RATE_TIME`` (s normalised input).
RATE_TIME = 100.0
#: Time scale of strain_accumulation (s): ``c`` is the output change per 1000 s at full drive.
ACCUMULATION_TIME = 1000.0

_a = jnp.asarray


def fractional_delay(x, delay_samples):
    """``x(k - d)`` with linear interpolation for fractional ``d >= 0``; before the start, ``x(0)``."""
    n = x.shape[0]
    pos = jnp.clip(jnp.arange(n, dtype=jnp.float64) - delay_samples, 0.0, n - 1.0)
    i0 = jnp.floor(pos)
    frac = pos - i0
    i0 = i0.astype(jnp.int32)
    i1 = jnp.minimum(i0 + 1, n - 1)
    return x[i0] * (1.0 - frac) + x[i1] * frac


def _lowpass(x, dt, tau, z0=None):
    """Exact first-order lag of a ZOH signal, state starting at ``z0`` (default ``x(0)``: at rest; columns filtered
    independently)."""
    return _lowpass_decay(x, jnp.exp(-dt / tau), x[0] if z0 is None else z0)


def _lowpass_decay(x, a, z0):
    """``z(k) = a z(k-1) + (1 - a) x(k)`` from ``z(-1) = z0`` (``a = 0``: ``z = x``)."""

    def step(z, xk):
        z = a * z + (1.0 - a) * xk
        return z, z

    _, z = jax.lax.scan(step, jnp.asarray(z0, dtype=x.dtype), x)
    return z


def warp_input(s, c, b):
    """Monotone logistic warp of the normalised input that maps 0 -> 0 and 1 -> 1 (see `InputWarp`)."""
    lo, hi = jax.nn.sigmoid(-c / b), jax.nn.sigmoid((1.0 - c) / b)
    return (jax.nn.sigmoid((s - c) / b) - lo) / (hi - lo)


@register_effect
class Delay(AbstractInputEffect):
    """Transport delay of the drive (dead time of the driver, sensor or heat conduction)."""

    name: ClassVar[str] = "delay"
    lookalikes: ClassVar[tuple[str, ...]] = ("timing",)
    needs: ClassVar[tuple] = ("time",)
    physics: ClassVar[str] = (
        "The output responds to the input tau seconds late (amplifier/DAQ latency, heat conduction from the SMA wire into the polymer, sensor filtering)."
    )
    parameters: ClassVar[dict] = {"tau": "delay in seconds (> 0), fractional delays by linear interpolation"}
    synthetic: ClassVar[str] = "tau ~ U(2, 8) s"
    tau: jnp.ndarray = positive()

    def transform_input(self, x, dt):
        return fractional_delay(x, self.tau / dt)

    @classmethod
    def nonlinear(cls, ctx):
        return (Nonlinear("tau", Log(), 0.5),)

    @classmethod
    def grid(cls, ctx):
        return [cls(tau=_a(ctx["dt"] * 2.0**k)) for k in range(6)]

    @classmethod
    def probes(cls, ctx):
        return [cls(tau=_a(ctx["dt"]))]

    @classmethod
    def synthesise(cls, rng, ctx):
        return cls(tau=_a(rng.uniform(2, 8))), {}


@register_effect
class SensorLag(AbstractInputEffect):
    """First-order lag between the measured input and what the hysteresis sees (smoothing, unlike `Delay`)."""

    name: ClassVar[str] = "sensor_lag"
    lookalikes: ClassVar[tuple[str, ...]] = ("timing",)
    needs: ClassVar[tuple] = ("time",)
    physics: ClassVar[str] = (
        "The transforming material follows the measured input through a first-order lag: heat conduction from the bath "
        "or the thermocouple into the wire, or the sensor's own response time. The hysteresis sees x'(k) = x'(k-1) + "
        "(1 - exp(-dt/tau)) (x(k) - x'(k-1)), x'(0) = x(0) (exact for a zero-order-hold input); unlike a transport delay "
        "it smooths steps."
    )
    parameters: ClassVar[dict] = {"tau": "lag time constant in seconds (> 0)"}
    synthetic: ClassVar[str] = "tau ~ U(5, 20) s"
    tau: jnp.ndarray = positive()

    def transform_input(self, x, dt):
        return _lowpass(x, dt, self.tau)

    @classmethod
    def nonlinear(cls, ctx):
        return (Nonlinear("tau", Log(), 0.5),)

    @classmethod
    def grid(cls, ctx):
        # lags of 1 to 128 samples: thermocouple/heat-conduction lags span seconds to a minute
        return [cls(tau=_a(ctx["dt"] * 2.0**k)) for k in range(0, 8)]

    @classmethod
    def probes(cls, ctx):
        # a weak lag equals a weak delay to first order (x - tau dx/dt); longer lags carry the smoothing signature
        return [cls(tau=_a(ctx["dt"] * f)) for f in (1.0, 8.0, 32.0)]

    @classmethod
    def synthesise(cls, rng, ctx):
        return cls(tau=_a(rng.uniform(5, 20))), {}


@register_effect
class AmbientDrift(AbstractThermalEffect):
    """Slow drift of the ambient (thermal equilibrium) during the record."""

    name: ClassVar[str] = "ambient_drift"
    lookalikes: ClassVar[tuple[str, ...]] = ("thermal", "slow")
    needs: ClassVar[tuple] = ("time",)
    physics: ClassVar[str] = (
        "The ambient temperature (or the rest temperature of the actuator) drifts linearly during the record, shifting the thermal state the hysteresis sees."
    )
    parameters: ClassVar[dict] = {
        "drift": "change of the thermal state per 1000 s in units of q_ref = u_span^2 (cascade) or of the input span (EUPI base); signed"
    }
    synthetic: ClassVar[str] = "drift ~ +-U(0.005, 0.02) q_ref per 1000 s"
    drift: jnp.ndarray

    def ambient(self, t, q_ref):
        return self.drift * q_ref * t / DRIFT_TIME

    def without_thermal(self, x, t, hysteresis):
        # a bare hysteresis base (temperature input): the input itself drifts, in units of its span
        return x + self.drift * hysteresis.u_span * t / DRIFT_TIME

    @classmethod
    def nonlinear(cls, ctx):
        return (Nonlinear("drift", Linear(), 0.005),)

    @classmethod
    def grid(cls, ctx):
        return [cls(drift=_a(d)) for d in (-0.05, -0.01, 0.01, 0.05)]

    @classmethod
    def probes(cls, ctx):
        # both signs: the thermal state is rectified at zero (u_eff = sqrt(max(q, 0))), so a falling ambient does
        # nothing while the actuator rests and a rising one acts mostly then: the signatures are not mirror images
        return [cls(drift=_a(d)) for d in (0.01, -0.01)]

    @classmethod
    def synthesise(cls, rng, ctx):
        return cls(drift=_a(ctx["sign"] * rng.uniform(0.005, 0.02))), {}


@register_effect
class ResistanceTC(AbstractThermalEffect):
    """Temperature coefficient of the wire resistance: Joule heating falls as the wire warms."""

    name: ClassVar[str] = "resistance_tc"
    lookalikes: ClassVar[tuple[str, ...]] = ("thermal",)
    needs: ClassVar[tuple] = ("thermal",)
    physics: ClassVar[str] = (
        "R = R0 (1 + beta q / q_ref): at constant voltage the heating power U^2/R falls as the wire warms, so hot states are reached more slowly and saturate lower."
    )
    parameters: ClassVar[dict] = {"beta": "relative resistance increase at q = q_ref (> 0)"}
    synthetic: ClassVar[str] = "beta ~ U(0.2, 0.6)"
    beta: jnp.ndarray = positive()

    def heating(self, heat, q, q_ref):
        return heat / (1.0 + (self.beta / q_ref) * jnp.maximum(q, 0.0))

    @classmethod
    def nonlinear(cls, ctx):
        return (Nonlinear("beta", Log(), 0.5),)

    @classmethod
    def grid(cls, ctx):
        return [cls(beta=_a(b)) for b in (0.1, 0.4, 1.2)]

    @classmethod
    def probes(cls, ctx):
        return [cls(beta=_a(0.05))]

    @classmethod
    def synthesise(cls, rng, ctx):
        return cls(beta=_a(rng.uniform(0.2, 0.6))), {}


@register_effect
class AsymmetricCooling(AbstractThermalEffect):
    """Different thermal time constants for heating and cooling."""

    name: ClassVar[str] = "asymmetric_cooling"
    lookalikes: ClassVar[tuple[str, ...]] = ("thermal",)
    needs: ClassVar[tuple] = ("thermal",)
    physics: ClassVar[str] = (
        "Cooling (heat loss to a still environment, latent heat of the reverse transformation) runs at a different rate than "
        "Joule heating: while the state falls the rate is k1 exp(log_ratio) / (1 + latent exp(-((q / q_ref - q_tr) / "
        "width)^2)): a uniform ratio, and the latent heat the reverse transformation releases in a band of temperatures "
        "(q_tr its centre, width its half-width, both as fractions of q_ref) that holds the cooling back there."
    )
    parameters: ClassVar[dict] = {
        "log_ratio": "log of cooling rate / heating rate (signed)",
        "latent": "extra heat capacity at the centre of the transformation band, relative (>= 0; 0: no band)",
        "q_tr": "centre of the band, fraction of q_ref",
        "width": "half-width of the band, fraction of q_ref (> 0)",
    }
    synthetic: ClassVar[str] = "log_ratio ~ +-U(0.3, 0.7), no band"
    #: Range of the band's centre and width (fractions of q_ref) in a fit.
    Q_TR_RANGE: ClassVar[tuple] = (0.02, 1.2)
    WIDTH_RANGE: ClassVar[tuple] = (0.02, 0.6)
    log_ratio: jnp.ndarray
    # defaults (no band): models saved before the band existed load and run unchanged
    latent: jnp.ndarray = eqx.field(default=0.0, converter=as_float_array)
    q_tr: jnp.ndarray = eqx.field(default=0.5, converter=as_float_array)
    width: jnp.ndarray = eqx.field(default=0.2, converter=as_float_array)

    def rate(self, rate, target, q, q_ref):
        band = self.latent * jnp.exp(-jnp.square((q / q_ref - self.q_tr) / self.width))
        return jnp.where(target < q, rate * jnp.exp(self.log_ratio) / (1.0 + band), rate)

    @classmethod
    def nonlinear(cls, ctx):
        return (
            Nonlinear("log_ratio", Linear(), 0.2),
            Nonlinear("latent", Log(), 0.5),
            Nonlinear("q_tr", LogBox(*cls.Q_TR_RANGE), 0.5),
            Nonlinear("width", LogBox(*cls.WIDTH_RANGE), 0.5),
        )

    @classmethod
    def grid(cls, ctx):
        ratio = [cls(log_ratio=_a(r), latent=_a(0.01)) for r in (-0.7, -0.25, 0.25, 0.7)]
        band = [cls(log_ratio=_a(0.0), latent=_a(2.0), q_tr=_a(c), width=_a(0.15)) for c in (0.25, 0.5, 0.75)]
        return ratio + band

    @classmethod
    def probes(cls, ctx):
        return [cls(log_ratio=_a(0.05), latent=_a(0.01))]

    @classmethod
    def synthesise(cls, rng, ctx):
        return cls(log_ratio=_a(ctx["sign"] * rng.uniform(0.3, 0.7))), {}


@register_effect
class NonlinearCooling(AbstractThermalEffect):
    """Convective/radiative cooling that grows faster than linearly with temperature."""

    name: ClassVar[str] = "nonlinear_cooling"
    lookalikes: ClassVar[tuple[str, ...]] = ("thermal",)
    needs: ClassVar[tuple] = ("thermal",)
    physics: ClassVar[str] = (
        "Heat loss k1 q (1 + gamma q / q_ref): natural convection and radiation make hot states cool faster (and saturate lower) than Newton's law."
    )
    parameters: ClassVar[dict] = {"gamma": "relative extra loss at q = q_ref (> 0)"}
    synthetic: ClassVar[str] = "gamma ~ U(0.2, 0.6)"
    gamma: jnp.ndarray = positive()

    def loss(self, q, q_ref):
        return 1.0 + (self.gamma / q_ref) * jnp.maximum(q, 0.0)

    @classmethod
    def nonlinear(cls, ctx):
        return (Nonlinear("gamma", Log(), 0.5),)

    @classmethod
    def grid(cls, ctx):
        return [cls(gamma=_a(g)) for g in (0.1, 0.4, 1.2)]

    @classmethod
    def probes(cls, ctx):
        return [cls(gamma=_a(0.05))]

    @classmethod
    def synthesise(cls, rng, ctx):
        return cls(gamma=_a(rng.uniform(0.2, 0.6))), {}


@register_effect
class InputWarp(AbstractWarpEffect):
    """Transformation warp: the hysteresis acts on a sigmoidal (CDF-like) function of the input."""

    name: ClassVar[str] = "input_warp"
    lookalikes: ClassVar[tuple[str, ...]] = ("static_map",)
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
    synthetic: ClassVar[str] = "c ~ U(0.4, 0.6), b ~ U(0.1, 0.2) (normalised effective voltage)"
    c: jnp.ndarray
    b: jnp.ndarray = positive()

    def warp(self, x, hysteresis):
        return hysteresis.denormalise(warp_input(hysteresis.normalise(x), self.c, self.b))

    @classmethod
    def nonlinear(cls, ctx):
        return (Nonlinear("c", Linear(), 0.1), Nonlinear("b", Log(), 0.5))

    @classmethod
    def grid(cls, ctx):
        return [cls(c=_a(c), b=_a(b)) for c in (0.3, 0.5, 0.7) for b in (0.05, 0.15, 0.5)]

    @classmethod
    def probes(cls, ctx):
        return [cls(c=_a(c), b=_a(3.0)) for c in (0.25, 0.5, 0.75)]

    @classmethod
    def synthesise(cls, rng, ctx):
        return cls(c=_a(rng.uniform(0.4, 0.6)), b=_a(rng.uniform(0.1, 0.2))), {}


@register_effect
class RateDependence(AbstractThresholdEffect):
    """Rate-dependent hysteresis: loop width grows with the (low-passed) rate of the hysteresis input."""

    name: ClassVar[str] = "rate_dependence"
    lookalikes: ClassVar[tuple[str, ...]] = ("timing",)
    needs: ClassVar[tuple] = ("time",)
    physics: ClassVar[str] = (
        "Play thresholds widen with the rate of the hysteresis input, r(k) = r (1 + c |v(k)| 100 s), v the rate ds/dt "
        "of the normalised input through a first-order lag of time constant tau (viscous friction in the polymer, "
        "rate-dependent phase transformation: the material's own velocity state, not the instantaneous difference of "
        "samples; tau = 0: the instantaneous rate). v starts at rest."
    )
    parameters: ClassVar[dict] = {
        "c": "threshold widening per unit normalised rate (per 100 s) (> 0)",
        "tau": "time constant (s) of the lag through which the rate acts, fitted within [dt / 2, 60 s]; 0: instantaneous",
    }
    synthetic: ClassVar[str] = "c ~ U(0.5, 1.5), tau = 0"
    #: upper end (s) of the fitted ``tau`` (slower than this, a rate is a level: the thermal family's territory)
    TAU_MAX: ClassVar[float] = 60.0
    c: jnp.ndarray = positive()
    # default 0 (the instantaneous rate): models saved before the field existed load and run unchanged
    tau: jnp.ndarray = eqx.field(default=0.0, converter=as_float_array)

    def threshold_scale(self, x, dt, hysteresis):
        s = hysteresis.normalise(x)
        v = jnp.diff(s, prepend=s[:1]) / dt * RATE_TIME
        on = self.tau > 0.0
        # where-guarded: tau = 0 is a plain pass-through with finite gradients
        a = jnp.where(on, jnp.exp(-dt / jnp.where(on, self.tau, 1.0)), 0.0)
        return 1.0 + self.c * jnp.abs(_lowpass_decay(v, a, 0.0))

    @classmethod
    def tau_bounds(cls, dt):
        lo = 0.5 * float(dt)
        return lo, max(cls.TAU_MAX, 8.0 * lo)

    @classmethod
    def nonlinear(cls, ctx):
        return (Nonlinear("c", Log(), 0.5), Nonlinear("tau", LogBox(*cls.tau_bounds(ctx["dt"])), 0.5))

    @classmethod
    def grid(cls, ctx):
        # weak to strong widening (a start far above the record's own leaves the simplex worse than the base: an
        # independent ambient-drift record (s3010) at c = 0.1 profiled 1.6x the base's RMSE), the lag from one sample to 8 s
        return [cls(c=_a(c), tau=_a(t)) for c in (0.003, 0.03, 0.3) for t in cls._taus(ctx, (ctx["dt"], 2.0, 8.0))]

    @classmethod
    def _taus(cls, ctx, taus):
        # inside the fitted range, a factor 2 off its ends (where the logistic map of `LogBox` is flat)
        lo, hi = cls.tau_bounds(ctx["dt"])
        return list(dict.fromkeys(float(np.clip(t, 2.0 * lo, 0.5 * hi)) for t in taus))

    @classmethod
    def probes(cls, ctx):
        return [cls(c=_a(0.05), tau=_a(t)) for t in cls._taus(ctx, (ctx["dt"], 2.0))]

    @classmethod
    def synthesise(cls, rng, ctx):
        return cls(c=_a(rng.uniform(0.5, 1.5))), {}


@register_effect
class Creep(AbstractFeatureEffect):
    """Slow viscoelastic relaxation (creep) of the polymer; a bounded fraction of the output relaxes."""

    name: ClassVar[str] = "creep"
    lookalikes: ClassVar[tuple[str, ...]] = ("slow", "timing")  # with g = 1 creep is an output lag
    needs: ClassVar[tuple] = ("time",)
    physics: ClassVar[str] = (
        "A fraction g of the output follows the hysteresis output H through a slow first-order lag L (time constant tau, "
        "seconds to minutes): y = (1 - g) H + g L[H]. After a step the output keeps relaxing while the input is held: "
        "towards the step (g > 0, creep) or back from an overshoot (g < 0, recovery). A relaxation is bounded: |g| <= 1 "
        "(at most the whole step creeps or overshoots) and tau lies between a few samples and the record length (a longer "
        "tau cannot be told from a ramp, which is ambient_drift); the diagnosis fits within these bounds. The creep state at "
        "t = 0 is part of the model: a record that starts soon after the actuator moved has not finished creeping, so L "
        "starts at (1 - unsettled) H(0) (unsettled = 0: settled; 1: no creep yet), |unsettled| <= U_MAX."
    )
    parameters: ClassVar[dict] = {
        "g": "fraction of the output that creeps, signed, |g| <= G_MAX = 1",
        "tau": "creep time constant in seconds, fitted within [TAU_MIN_SAMPLES dt, record length]",
        "unsettled": "fraction of the settled creep state still missing at t = 0 (0: settled), |unsettled| <= U_MAX",
    }
    synthetic: ClassVar[str] = "g ~ +-U(0.08, 0.2) (creep or recovery from an overshoot), tau ~ U(100, 400) s"
    #: Bounds used when fitting (models saved with values outside them still load and run unchanged).
    G_MAX: ClassVar[float] = 1.0
    TAU_MIN_SAMPLES: ClassVar[float] = 2.0
    #: Bound of ``unsettled``: the state at t = 0 lies between 1.5 H(0) below and above its settled value.
    U_MAX: ClassVar[float] = 1.5
    g: jnp.ndarray
    tau: jnp.ndarray = positive()
    # default 0 (settled at t = 0): models saved before the field existed load and run unchanged
    unsettled: jnp.ndarray = eqx.field(default=0.0, converter=as_float_array)

    def filter_features(self, F, dt):
        # The offset column (all ones; any column equal to 1 throughout is collinear with it) is the sensor zero, not a
        # strain: it does not creep, whatever the initial state.
        offset = jnp.all(F == 1.0, axis=0)
        z0 = jnp.where(offset, F[0], (1.0 - self.unsettled) * F[0])
        return F + self.g * (_lowpass(F, dt, self.tau, z0) - F)

    @classmethod
    def tau_bounds(cls, dt, duration):
        """Fitting range of ``tau`` (s): a few samples up to the (training) record length."""
        lo = cls.TAU_MIN_SAMPLES * float(dt)
        return lo, max(float(duration), 2.0 * lo)

    @classmethod
    def taus(cls, ctx):
        """Starting/probe time constants (30 s .. 1000 s) clipped inside the fitting range, duplicates dropped.

        Kept a factor 2 off the bounds, where the logistic map of `LogBox` is flat and a simplex would stall.
        """
        lo, hi = cls.tau_bounds(ctx["dt"], ctx["duration"])
        lo, hi = min(2.0 * lo, np.sqrt(lo * hi)), max(0.5 * hi, np.sqrt(lo * hi))
        return list(dict.fromkeys(float(np.clip(t, lo, hi)) for t in (30.0, 100.0, 300.0, 1000.0)))

    @classmethod
    def nonlinear(cls, ctx):
        # bounded (see the class): g = G_MAX tanh(p), log tau a logistic map onto the fitting range, so a fit cannot
        # turn the relaxation into a huge-gain integrator (g -> -inf, tau >> record: a ramp)
        return (
            Nonlinear("g", Tanh(cls.G_MAX), 0.05),
            Nonlinear("tau", LogBox(*cls.tau_bounds(ctx["dt"], ctx["duration"])), 0.5),
            Nonlinear("unsettled", Tanh(cls.U_MAX), 0.3),
        )

    @classmethod
    def grid(cls, ctx):
        # settled, and a record that starts before any creep (the start transient of a warm record)
        return [cls(g=_a(g), tau=_a(t), unsettled=_a(u0)) for u0 in (0.0, 1.0) for g in (-0.1, 0.1, 0.3) for t in cls.taus(ctx)]

    @classmethod
    def probes(cls, ctx):
        return [cls(g=_a(0.05), tau=_a(t)) for t in cls.taus(ctx)]

    @classmethod
    def synthesise(cls, rng, ctx):
        return cls(g=_a(ctx["sign"] * rng.uniform(0.08, 0.2)), tau=_a(rng.uniform(100, 400))), {}


def _sech2(x):
    """``1 / cosh(x)**2`` as ``4 e^(-2|x|) / (1 + e^(-2|x|))**2``: the same values, but cosh(x)**2 overflowed (a
    RuntimeWarning on the user's stderr in `smafl diagnose`) for |x| > ~355, and ``1 - tanh(x)**2`` loses all digits
    far out (tanh rounds to 1).  |x| is capped at 350 (the value floored at 4e-304), so that exp never underflows."""
    a = np.exp(-2.0 * np.minimum(np.abs(np.asarray(x, dtype=np.float64)), 350.0))
    return 4.0 * a / (1.0 + a) ** 2


@register_effect
class OutputSaturation(AbstractOutputEffect):
    """Output saturation: steep sigmoidal SMA transformation between two stroke limits."""

    name: ClassVar[str] = "output_saturation"
    lookalikes: ClassVar[tuple[str, ...]] = ("static_map",)
    needs: ClassVar[tuple] = ()
    physics: ClassVar[str] = (
        "The stroke is bounded by the completed martensite/austenite transformation: y = m + w tanh((H - m) / w), a monotone sigmoid between m - w and m + w that tends to the identity as w grows."
    )
    parameters: ClassVar[dict] = {
        "m": "centre of the saturation map (output units)",
        "w": "half-width: the output stays within m +- w (> 0)",
    }
    synthetic: ClassVar[str] = "m = output mid-level, w = half output range x U(0.9, 1.3)"
    linear_in_weights: ClassVar[bool] = False
    m: jnp.ndarray
    w: jnp.ndarray = positive()

    def output(self, y, dt, load):
        return self.m + self.w * jnp.tanh((y - self.m) / self.w)

    def profile_link(self):
        m, w = float(self.m), float(self.w)
        return OutputLink(
            forward=lambda z: m + w * np.tanh((z - m) / w),
            # the inverse diverges at the limits: targets are clipped just inside them
            inverse=lambda y: m + w * np.arctanh(np.clip((y - m) / w, -0.995, 0.995)),
            slope=lambda z: _sech2((z - m) / w),
        )

    @classmethod
    def nonlinear(cls, ctx):
        return (Nonlinear("m", Linear(), 0.05 * ctx["y_range"]), Nonlinear("w", Log(), 0.2))

    @classmethod
    def grid(cls, ctx):
        yr, ym = ctx["y_range"], ctx["y_mid"]
        return [cls(m=_a(ym + dm * yr), w=_a(f * yr / 2)) for dm in (-0.1, 0.0, 0.1) for f in (1.02, 1.2, 2.0)]

    @classmethod
    def probes(cls, ctx):
        yr, lo = ctx["y_range"], ctx["y_lo"]
        return [cls(m=_a(lo + f * yr), w=_a(3.0 * yr)) for f in (0.25, 0.5, 0.75)]

    @classmethod
    def synthesise(cls, rng, ctx):
        lo, hi = ctx["y_lo"], ctx["y_hi"]
        return cls(m=_a(0.5 * (lo + hi)), w=_a(0.5 * (hi - lo) * rng.uniform(0.9, 1.3))), {}


@register_effect
class LoadDependence(AbstractOutputEffect):
    """Stroke and offset change with the mechanical load (needs a load column)."""

    name: ClassVar[str] = "load_dependence"
    lookalikes: ClassVar[tuple[str, ...]] = ("static_map",)
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
    synthetic: ClassVar[str] = (
        "load: piecewise-constant steps in [1, 3] every 150-400 s; a ~ +-U(0.05, 0.15), b ~ +-U(0.05, 0.15) mm"
    )
    a: jnp.ndarray
    b: jnp.ndarray
    load_ref: jnp.ndarray
    load_scale: jnp.ndarray

    def output(self, y, dt, load):
        if load is None:  # no load signal: the model predicts at its reference load
            return y
        l_ = (jnp.asarray(load, dtype=jnp.float64) - self.load_ref) / self.load_scale
        return y * (1.0 + self.a * l_) + self.b * l_

    def held_fields(self, *, load=True):
        return ("load_ref", "load_scale") if load else ("a", "b", "load_ref", "load_scale")

    def profile_design(self, A, t, load):
        # y = (A theta)(1 + a l) + b l: linear in (theta, b) for fixed a
        if load is None:
            raise ValueError("load_dependence needs a load signal to be fitted")
        l_ = (np.asarray(load) - float(self.load_ref)) / float(self.load_scale)
        return np.column_stack([A * (1.0 + float(self.a) * l_)[:, None], l_]), ("b",)

    @classmethod
    def nonlinear(cls, ctx):
        return (Nonlinear("a", Linear(), 0.05),)

    @classmethod
    def grid(cls, ctx):
        return [cls(a=_a(x), b=_a(0.0), load_ref=_a(ctx["load_ref"]), load_scale=_a(ctx["load_scale"])) for x in (-0.2, 0.0, 0.2)]

    @classmethod
    def probes(cls, ctx):
        yr = ctx["y_range"]
        return [
            cls(a=_a(0.05), b=_a(0.0), load_ref=_a(ctx["load_ref"]), load_scale=_a(ctx["load_scale"])),
            cls(a=_a(0.0), b=_a(0.05 * yr), load_ref=_a(ctx["load_ref"]), load_scale=_a(ctx["load_scale"])),
        ]

    @classmethod
    def synthesise(cls, rng, ctx):
        dt, n = ctx["dt"], ctx["n"]
        load = np.empty(n)
        i = 0
        while i < n:
            k = int(rng.uniform(150, 400) / dt)
            load[i : i + k] = rng.uniform(1.0, 3.0)
            i += k
        eff = cls(
            a=_a(ctx["sign"] * rng.uniform(0.05, 0.15)),
            b=_a((1 if rng.random() < 0.5 else -1) * rng.uniform(0.05, 0.15)),
            load_ref=_a(float(load.mean())),
            load_scale=_a(float(load.std())),
        )
        return eff, {"load_N": load}


@register_effect
class StrainAccumulation(AbstractLinearEffect):
    """Strain that accumulates while the wire is driven (hot/transformed) and stays (permanent, one parameter ``c``)."""

    name: ClassVar[str] = "strain_accumulation"
    lookalikes: ClassVar[tuple[str, ...]] = ("slow",)
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
    synthetic: ClassVar[str] = "c ~ +-U(0.08, 0.25) mm per 1000 s at full drive (0.1-0.33 mm over the record)"
    linear_fields: ClassVar[tuple] = ("c",)
    c: jnp.ndarray

    def columns(self, model, u, dt):
        """Output change per unit ``c``: the accumulated strain ``D(t)`` (see the class)."""
        dt = jnp.asarray(1.0 if dt is None else dt, dtype=jnp.float64)
        s = model.hysteresis.normalise(model.hysteresis_input(u, dt))
        phi = jnp.clip(s - s[0], 0.0, 1.0)
        # a plain integral (rectangle rule; phi(0) = 0, so D(0) = 0): a cumsum, no recurrence
        return {"c": -jnp.cumsum(phi) * dt / ACCUMULATION_TIME}

    @classmethod
    def nonlinear(cls, ctx):
        return ()  # c is linear (profiled with the gains)

    @classmethod
    def grid(cls, ctx):
        return [cls(c=_a(0.0))]  # a single start: c is profiled with the gains

    @classmethod
    def probes(cls, ctx):
        return [cls(c=_a(0.01 * ctx["y_range"]))]

    @classmethod
    def synthesise(cls, rng, ctx):
        return cls(c=_a(ctx["sign"] * rng.uniform(0.08, 0.25))), {}
