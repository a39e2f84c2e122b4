"""Joule-heating thermal model, eqs. (4)-(7).

    dT/dt = K1 (T0 - T) + K2 J(t),   J = U^2   (R absorbed in K2, see below)

The paper identifies ``T(s) / M'(s) = 0.04172 / (s + 0.04988)`` from the
squared drive voltage ``M' = U^2`` (eq. 7; its eq. 6 contradicts it and is not
used), so the defaults are ``k1 = 0.04988 1/s`` (time constant ~20 s) and
``k2 = 0.04172``.  The resistance is quoted as both 38 and 380 ohm; because the
identified model is written in ``U^2`` the resistance is absorbed into ``k2``
(``k2 = K2_phys / R``) and never needed.  The state ``theta = T - T0`` is in
the units the paper's lag maps ``U^2`` to (displacement scale).

Discretisation is exact for a piecewise-constant input: the sample ``U(k)``
is taken to be the voltage held over the interval ``(t_{k-1}, t_k]`` that ends
at the sample instant, so

    theta(k) = a theta(k-1) + (1 - a) g U(k)^2,   a = exp(-k1 dt),  g = k2 / k1.

With this convention a fast thermal state (``k1 dt >> 1``) gives
``theta(k) = g U(k)^2`` exactly, so the cascade reduces to the voltage-domain
EUPI.  Initial state: ``"steady"`` (default: at rest with the first input,
``theta(-1) = g U(0)^2``, which is ambient for records that start at 0 V),
``"ambient"`` (``theta(-1) = 0``) or ``"given"`` (the state a constant ``u0`` V
would hold).  A joint fit of several records may hold one ``u0`` per record
(a vector): each record then starts from its own state, and `for_record` picks one.

Optional slow thermal mode (``slow_k1``, ``slow_ratio``; both None: one mode, the paper's model).  An SMA wire wound on a
nylon line, in a sleeve or clamped to a heat sink warms a second, slower mass, and the wire then relaxes towards
``(U^2 + r z) / (1 + r)`` instead of ``U^2``, with ``z`` the heat the slow mass has taken up:

    z(k) = a_s z(k-1) + (1 - a_s) U(k)^2,   a_s = exp(-slow_k1 dt),   r = slow_ratio > 0

(share ``c = r / (1 + r)`` of the drive's heat reaches the wire through the slow mass).  The steady state is
unchanged (``theta = g U^2``), so the hysteresis input and every start rule mean what they meant; the slow mass starts
in the same state as the wire (steady, ambient or the state a constant ``u0`` would hold).  With ``slow_k1`` and the
wire's ``k1`` this is the general two-pole, one-zero linear thermal network with the zero between the poles that a
wire coupled to one other mass gives.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.typing import ArrayLike

from .. import _config  # noqa: F401
from .._errors import UserInputError
from .._io import register_model
from ..ops import affine
from ._constraints import positive
from ._operators import MODEL_METHODS, resolve_method

__all__ = ["JouleThermal", "PAPER_K1", "PAPER_K2", "thermal_step", "effective_voltage"]

INITS = ("steady", "ambient", "given")
LAGS = (0, 1)

PAPER_K1 = 0.04988
PAPER_K2 = 0.04172


def thermal_step(theta: ArrayLike, x: ArrayLike, a: ArrayLike, g: ArrayLike) -> tuple[jax.Array, jax.Array]:
    """One exact ZOH step: ``(theta(k-1), U(k)) -> (theta(k), theta(k))``."""
    new = a * theta + (1.0 - a) * g * x * x
    return new, new


def _safe_sqrt(x):
    # sqrt has an infinite derivative at 0; the double-where keeps gradients finite
    # (0 at and below zero) for records that rest at 0 V.
    pos = x > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, x, 1.0)), 0.0)


def effective_voltage(theta: ArrayLike, k1: ArrayLike, k2: ArrayLike) -> jax.Array:
    """Quasi-static voltage the hysteresis sees: ``sqrt(theta k1 / k2)`` (= U at steady state)."""
    return _safe_sqrt(theta * (k1 / k2))


@register_model
class JouleThermal(eqx.Module):
    """First-order Joule thermal model driven by ``U^2``."""

    #: Evaluation forms of the ``method`` field (`model_with_method` switches every part that declares some).
    evaluation_methods = MODEL_METHODS

    k1: jnp.ndarray = positive(default_factory=lambda: jnp.asarray(PAPER_K1))
    k2: jnp.ndarray = positive(default_factory=lambda: jnp.asarray(PAPER_K2))
    init: str = eqx.field(static=True, default="steady")
    # init="given": the record starts at the thermal state a constant voltage u0 would hold
    # (u0 -> 0: cold, u0 = u[0]: at equilibrium); fitted, so warm / half-warm / cold starts are all reachable.
    u0: jnp.ndarray | None = positive(default=None)
    # evaluation form of the linear recurrence (smafl_jax.ops.affine): "scan", "assoc", "chunked",
    # "segmented" (agree with scan to rounding, ~1e-15 relative) or "auto" (choose_model_method)
    method: str = eqx.field(static=True, default="scan")
    # Samples between a drive sample and the heating it causes: 0 = U(k) heats the interval that ends at sample k
    # (zero-order hold on the current sample, as above); 1 = from the next interval on (the drive logged at the start
    # of the interval it acts over, as many DAQs do).  A sampling convention of the rig, not physics: on sharp
    # drives (PWM, steps) a one-sample mismatch leaves structure that a "delay" effect then explains.  Screened on
    # held-out data by the diagnosis (`smafl_jax.diagnosis.refined_base`), not trained.
    lag: int = eqx.field(static=True, default=0)
    # the optional slow thermal mode (module docstring): its rate (1/s) and the ratio r of the heat reaching the wire
    # through it to the heat reaching it directly; both None (the default) or both set
    slow_k1: jnp.ndarray | None = positive(default=None)
    slow_ratio: jnp.ndarray | None = positive(default=None)

    def __check_init__(self):
        if (self.slow_k1 is None) != (self.slow_ratio is None):
            raise ValueError("JouleThermal needs slow_k1 and slow_ratio together (a slow thermal mode) or neither")
        if self.lag not in LAGS:
            raise ValueError(f"JouleThermal lag must be one of {LAGS} samples, got {self.lag!r}")
        if self.method not in MODEL_METHODS:
            raise ValueError(f"JouleThermal method must be one of {MODEL_METHODS}, got {self.method!r}")
        if self.init not in INITS:
            raise ValueError(f"JouleThermal init must be one of {INITS}, got {self.init!r}")
        if (self.init == "given") != (self.u0 is not None):
            raise ValueError("JouleThermal needs u0 exactly when init='given' (the initial effective voltage, V)")
        if self.u0 is not None and jnp.ndim(self.u0) > 1:
            raise ValueError(f"JouleThermal u0 must be a scalar or one value per record (1-D), got shape {jnp.shape(self.u0)}")

    @property
    def n_record_starts(self) -> int | None:
        """Number of per-record starts (``u0`` a vector, from a joint fit of several records), else None."""
        return None if self.u0 is None or jnp.ndim(self.u0) == 0 else int(jnp.shape(self.u0)[0])

    def for_record(self, i: int) -> JouleThermal:
        """This stage as it starts record ``i`` of a joint fit: its own ``u0`` when the fit kept one per record."""
        if self.n_record_starts is None:
            return self
        return eqx.tree_at(lambda t: t.u0, self, self.u0[i])  # a leaf swap: no __init__, so it works on traced models

    def with_record_starts(self, u0s) -> JouleThermal:
        """Copy that starts record ``i`` of a joint fit at the state a constant ``u0s[i]`` V would hold."""
        return dataclasses.replace(self, init="given", u0=jnp.asarray(u0s, dtype=jnp.float64).reshape(-1))

    @property
    def gain(self):
        """Steady-state gain ``k2 / k1`` from ``U^2`` to ``theta``."""
        return self.k2 / self.k1

    def simulate(self, u, dt):
        """Thermal state ``theta(k)`` for voltage record ``u`` sampled every ``dt`` seconds."""
        u = jnp.asarray(u, dtype=jnp.float64)
        dt = jnp.asarray(dt, dtype=jnp.float64)
        a = jnp.exp(-self.k1 * dt)
        g = self.gain
        theta0 = self.initial_state(u[0])
        # theta(k) = a theta(k-1) + b(k): the thermal_step recurrence as an affine scan (same products per sample)
        if self.has_slow_mode:
            b = (1.0 - a) * g * self.heat(u, dt)
        else:  # the one-mode products in their old order: fits without a slow mode stay bit for bit what they were
            v = self.drive_samples(u)
            b = (1.0 - a) * g * v * v
        return affine(a, b, theta0, method=resolve_method(self.method, u.shape[0], 1, "JouleThermal method"))

    @property
    def has_slow_mode(self) -> bool:
        """True when the model holds a slow thermal mode (``slow_k1``, ``slow_ratio``)."""
        return self.slow_k1 is not None

    def with_slow_mode(self, slow_k1: float, slow_ratio: float) -> JouleThermal:
        """Copy with a slow thermal mode of rate ``slow_k1`` (1/s) and ratio ``slow_ratio`` (module docstring)."""
        f = jnp.float64
        return dataclasses.replace(self, slow_k1=jnp.asarray(slow_k1, dtype=f), slow_ratio=jnp.asarray(slow_ratio, dtype=f))

    def heat(self, u, dt):
        """The squared drive the wire relaxes to at each sample (V^2): ``U^2`` of the drive sample that heats the interval
        (`drive_samples`), mixed with the slow mass's share when the model has a slow mode."""
        v = self.drive_samples(jnp.asarray(u, dtype=jnp.float64))
        h = v * v
        if not self.has_slow_mode:
            return h
        a_s = jnp.exp(-self.slow_k1 * jnp.asarray(dt, dtype=jnp.float64))
        # the slow mass starts where the wire does (in V^2: theta(-1) / g)
        z0 = self.initial_state(v[0]) / self.gain
        z = affine(a_s, (1.0 - a_s) * h, z0, method=resolve_method(self.method, h.shape[0], 1, "JouleThermal method"))
        return (h + self.slow_ratio * z) / (1.0 + self.slow_ratio)

    def sample_start(self, u_first):
        """State of `sample_step` before the first sample: ``theta`` by the ``init`` rule, and with a slow mode the pair
        ``(theta, z)``, the slow mass where the wire is (V^2 units)."""
        theta = self.initial_state(u_first)
        return (theta, theta / self.gain) if self.has_slow_mode else theta

    def sample_step(self, state, u, dt):
        """One sample of `simulate` for a loop that chooses each drive sample as it goes (the closed loop): ``(state,
        U(k)) -> (state, theta(k))``, the drive sample heating the interval that ends at sample k."""
        a = jnp.exp(-self.k1 * dt)
        if not self.has_slow_mode:
            return thermal_step(state, u, a, self.gain)
        # `heat` one sample at a time: the slow mass low-passes U^2, the wire relaxes to the mixture
        theta, z = state
        a_s = jnp.exp(-self.slow_k1 * dt)
        z = a_s * z + (1.0 - a_s) * u * u
        heat = (u * u + self.slow_ratio * z) / (1.0 + self.slow_ratio)
        theta = a * theta + (1.0 - a) * self.gain * heat
        return (theta, z), theta

    def drive_samples(self, u):
        """The drive sample that heats each interval: ``u`` itself, or with ``lag=1`` the previous one (u(-1) = u(0),
        the drive before the record held at its first value, consistent with every ``init`` rule)."""
        if self.lag == 0:
            return u
        return jnp.concatenate([u[:1], u[:-1]])

    def initial_state(self, u_first):
        """``theta`` before the first sample, by the ``init`` rule."""
        if self.init == "steady":
            return self.gain * u_first**2
        if self.init == "given":
            if self.n_record_starts is not None:  # a static shape: fails at trace time, before any scan runs
                raise UserInputError(
                    f"this thermal model holds one start per record of its joint fit ({self.n_record_starts} records): "
                    "run record i with model.for_record(i), or a new record with an initial-state rule "
                    "(steady, cold or estimate)"
                )
            return self.gain * self.u0**2 + 0.0 * u_first
        return jnp.zeros_like(u_first)

    def effective_voltage(self, theta):
        return effective_voltage(theta, self.k1, self.k2)

    def settles_within(self, dt: float, k1: float | None = None, samples: float = 1.0) -> bool:
        """True when the lag's time constant ``1 / k1`` (this model's, or the rate given) is at most ``samples`` samples
        of ``dt``: a lag that short is barely resolved by the record (quasi-static data), so a static hysteresis of the
        drive may explain it as well as the cascade does."""
        return float(self.k1 if k1 is None else k1) * float(dt) * float(samples) >= 1.0

    def start_voltage(self, u_first: float) -> float:
        """The initial effective voltage (V) this start rule gives a record whose first input is ``u_first`` (one
        shared start; the joint fit's per-record search starts from it)."""
        if self.init == "given":
            return float(self.u0)
        return float(u_first) if self.init == "steady" else 0.0

    def start_description(self) -> str:
        """The start state in words (report and fit notes)."""
        if self.init == "given" and self.n_record_starts is not None:
            each = ", ".join(f"{float(v):.4g}" for v in self.u0)
            return f"fitted per record: the state a constant {each} V would hold"
        if self.init == "given":
            return f"fitted: the state a constant {float(self.u0):.4g} V would hold"
        return "at rest with the first input" if self.init == "steady" else "cold (ambient)"

    def describe(self) -> list[str]:
        """The rates and the start state for a fit report (``report.md``), one line each."""
        k1, k2 = float(self.k1), float(self.k2)
        lines = [f"thermal: k1 = {k1:.6g} 1/s (time constant {1 / k1:.4g} s), k2 = {k2:.6g}"]
        if self.has_slow_mode:
            ks, r = float(self.slow_k1), float(self.slow_ratio)
            lines.append(
                f"slow thermal mode: rate {ks:.4g} 1/s (time constant {1 / ks:.4g} s), {100 * r / (1 + r):.3g} % of the "
                "heat reaches the wire through it"
            )
        return [*lines, f"thermal state at t = 0: {self.start_description()}"]
