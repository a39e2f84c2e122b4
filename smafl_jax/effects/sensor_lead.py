"""Catalogue effect `sensor_lead`: the input sensor lags the material, the hysteresis sees its lag undone (issue 14).

One self-contained class (the proof for issue 12 that a new effect is one class in one file); importing this module
registers it (``smafl_jax.effects`` imports it after the built-in catalogue, so it comes last in catalogue order).
"""

from __future__ import annotations

from typing import ClassVar

import jax
import jax.numpy as jnp

from .. import _config  # noqa: F401
from ..models._constraints import positive
from .protocol import AbstractInputEffect, Log, Nonlinear, register_effect

__all__ = ["SensorLead"]

_a = jnp.asarray


@register_effect
class SensorLead(AbstractInputEffect):
    """Lead-lag pre-stage ``(1 + lead s) / (1 + tau s)``: undoes a slow input sensor (``lead > tau``)."""

    name: ClassVar[str] = "sensor_lead"
    lookalikes: ClassVar[tuple[str, ...]] = ("timing",)
    needs: ClassVar[tuple] = ("time",)
    physics: ClassVar[str] = (
        "The input sensor responds more slowly than the material (a thermocouple in a water bath settles in 5-10 s while "
        "a thin wire transforms within 1 s), so the measured output-vs-input loop runs backwards. The hysteresis sees "
        "the sensor reading through the lead-lag H(s) = (1 + lead s) / (1 + tau s): a first-order sensor lag of time "
        "constant lead is undone and replaced by a short lag tau that filters the noise the inversion amplifies. "
        "Discrete form: the exact inverse of sensor_lag's zero-order-hold lag of time constant lead, then that lag with "
        "tau, x'(k) = b x'(k-1) + (1 - b) / (1 - a) (x(k) - a x(k-1)), a = exp(-dt/lead), b = exp(-dt/tau), at rest "
        "with x'(0) = x(0); so sensor_lead(lead, tau) after sensor_lag(lead) is sensor_lag(tau) exactly. Written as "
        "x' = z + g (x - z), z the zero-order-hold low-pass of x with tau and g = expm1(dt/tau) / expm1(dt/lead) (-> "
        "lead / tau as dt -> 0). lead = tau is the identity, lead < tau a partial lag (lead -> 0 is sensor_lag), "
        "lead > tau a lead."
    )
    parameters: ClassVar[dict] = {
        "lead": "lead time in seconds (> 0): the time constant of the sensor lag that is undone",
        "tau": "filter time constant in seconds (> 0): the lag put in its place (noise filter)",
    }
    synthetic: ClassVar[str] = "tau ~ U(1, 3) s, lead = tau x U(2, 3)"
    lead: jnp.ndarray = positive()
    tau: jnp.ndarray = positive()

    def transform_input(self, x, dt):
        # the recurrence form stays finite for any lead, tau > 0 (lead -> 0: a -> 0; tau -> 0: b -> 0)
        a, b = jnp.exp(-dt / self.lead), jnp.exp(-dt / self.tau)
        c = jnp.expm1(-dt / self.tau) / jnp.expm1(-dt / self.lead)  # (1 - b) / (1 - a)

        def step(carry, xk):
            yp, xp = carry
            yk = b * yp + c * (xk - a * xp)
            return (yk, xk), yk

        _, y = jax.lax.scan(step, (x[0], x[0]), x)  # at rest with the first sample: x'(0) = x(0)
        return y

    @classmethod
    def nonlinear(cls, ctx):
        return (Nonlinear("lead", Log(), 0.5), Nonlinear("tau", Log(), 0.5))

    @classmethod
    def grid(cls, ctx):
        # filters of 4 to 64 samples, leads 2x and 4x longer (the NiTi water steps: tau 1-5 s, lead 5-15 s at 10 Hz)
        return [cls(lead=_a(g * ctx["dt"] * k), tau=_a(ctx["dt"] * k)) for k in (4.0, 16.0, 64.0) for g in (2.0, 4.0)]

    @classmethod
    def probes(cls, ctx):
        # weak leads: x' - x = (g - 1)(x - z) ~ (g - 1) tau dx/dt for short tau (an advance); longer filters carry the
        # high-pass signature of undoing a slow sensor
        return [cls(lead=_a(1.2 * ctx["dt"] * f), tau=_a(ctx["dt"] * f)) for f in (1.0, 8.0, 32.0)]

    @classmethod
    def synthesise(cls, rng, ctx):
        tau = rng.uniform(1.0, 3.0)
        return cls(lead=_a(tau * rng.uniform(2.0, 3.0)), tau=_a(tau)), {}
