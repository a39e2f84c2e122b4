"""Closed-loop control simulation: cascade plant + PID / composite PID (section 4 of the paper).

Everything is one `jax.lax.scan` over samples, so a whole configuration (plant,
gains, compensator, reference) is a PyTree that `jax.vmap` batches (see
`smafl_jax.control._sweep`).

Sampling convention (chosen here; the paper gives no sample time).  At sample
``k`` (time ``t_k = k dt``) the controller measures ``y_m(k) = Q(y(k) + n(k))``
(noise ``n``, quantiser ``Q``), computes the drive ``u(k)`` and holds it over
``(t_k, t_{k+1}]``; the plant's ``y(k+1)`` is the output at the end of that
interval (this is the ZOH convention of `JouleThermal`).  ``y(0)`` is the plant
at rest with the voltage ``u_init`` (default 0 V).  Tracking metrics compare
``y_d(k)`` with the true (noise-free) ``y(k)``, k = 0..N-1, eq. (8).

Controller.  Discrete PID with
- proportional and integral action on the error ``e = y_d - y_m``,
  backward-Euler integrator ``I(k) = I(k-1) + ki dt e(k)``;
- derivative on the measurement (no derivative kick on reference steps),
  first-order filter ``tf``: ``D(k) = (tf D(k-1) - kd (y_m(k) - y_m(k-1))) / (tf + dt)``;
- output saturation to ``[umin, umax]`` (only positive voltages, 0..7.4 V);
- anti-windup by conditional integration ("clamping"): the integrator is frozen
  at a sample where integrating would push an already saturated drive further
  into saturation.

Composite PID = PID + integral-inverse (I-I) compensator, ``u = sat(u1 + u2)``.
The compensator is an integral loop around the *identified forward model* H
(its own copy of the model state, so plant and model may differ):
``du2/dt = K (y_d - H[u2])``, forward Euler ``u2(k) = clip(u2(k-1) + dt K (y_d(k) - yhat(k-1)))``
then ``yhat(k) = H[u2](k)``; ``u2`` is clipped to ``[umin, umax]`` too (its own
anti-windup: an unreachable reference cannot wind it up).  Choice of H
(documented): by default the identified *static hysteresis* (the
``hysteresis`` part of a cascade: EUPI, or any `smafl_jax.models._hysteresis` model), as in the paper ("based on the accurate
hysteresis model"); then ``u2`` converges to the quasi-static inverse voltage
and the PID handles the thermal lag.  ``hysteresis_only=False`` puts the whole
identified cascade (thermal lag included) inside the integral loop, which with
a pure integrator around a ~16-20 s lag is a lightly damped second-order loop.
"""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import _config  # noqa: F401
from ..models._simulate import check_sample_time, scalar_leaves_as_arrays

__all__ = [
    "PID",
    "IICompensator",
    "ClosedLoop",
    "plant_init",
    "plant_step",
    "simulate_closed_loop",
    "closed_loop_metrics",
    "reachable_output",
    "sine_reference",
    "step_reference",
    "PAPER_GAINS",
]

# Simulation gains of section 4.2 (Ziegler-Nichols tuned in the paper).
PAPER_GAINS = {"kp": 35.0, "ki": 20.0, "kd": 0.0, "K": 10.0}


def _f64(x):
    return jnp.asarray(x, dtype=jnp.float64)


class PID(eqx.Module):
    """Discrete PID with filtered derivative, output saturation and conditional-integration anti-windup."""

    kp: jnp.ndarray
    ki: jnp.ndarray
    kd: jnp.ndarray
    tf: jnp.ndarray  # derivative filter time constant (s)
    umin: jnp.ndarray
    umax: jnp.ndarray
    anti_windup: bool = eqx.field(static=True, default=True)

    def __init__(self, kp=35.0, ki=20.0, kd=0.0, tf=0.05, umin=0.0, umax=7.4, anti_windup=True):
        self.kp, self.ki, self.kd, self.tf = _f64(kp), _f64(ki), _f64(kd), _f64(tf)
        self.umin, self.umax = _f64(umin), _f64(umax)
        self.anti_windup = bool(anti_windup)

    def __check_init__(self):
        # Only concrete (unbatched or batched) numbers can be checked here; traced values pass.
        for name in ("tf",):
            v = getattr(self, name)
            if not isinstance(v, jax.core.Tracer) and np.any(np.asarray(v) <= 0):
                raise ValueError(f"PID {name} must be > 0, got {np.asarray(v)}")
        lo, hi = self.umin, self.umax
        if not isinstance(lo, jax.core.Tracer) and not isinstance(hi, jax.core.Tracer):
            if np.any(np.asarray(hi) <= np.asarray(lo)):
                raise ValueError(f"saturation range must have umax > umin, got [{np.asarray(lo)}, {np.asarray(hi)}]")


class IICompensator(eqx.Module):
    """Integral-inverse compensator ``du2/dt = K (y_d - H[u2])`` around an identified forward model."""

    model: Any  # Cascade or hysteresis model (EUPI, Preisach): the identified model (may differ from the plant)
    K: jnp.ndarray
    hysteresis_only: bool = eqx.field(static=True, default=True)

    def __init__(self, model, K=10.0, hysteresis_only=True):
        _parts(model)  # validates the model type
        self.model = model
        self.K = _f64(K)
        self.hysteresis_only = bool(hysteresis_only)

    @property
    def forward_model(self):
        """The H the integral loop runs on (static hysteresis by default, see module docstring)."""
        return self.model.hysteresis if self.hysteresis_only else self.model

    def to_forward_input(self, u):
        """Voltage -> the forward model's input: the steady hysteresis input (V^2 for a cascade that sees heat)."""
        return self.model.steady_drive(u) if self.hysteresis_only else u


class ClosedLoop(eqx.Module):
    """One closed-loop configuration: plant, controller, reference and sensor model (a PyTree)."""

    plant: Any
    pid: PID
    reference: jnp.ndarray  # y_d(k), k = 0..N-1 (mm)
    compensator: IICompensator | None = None
    noise_sd: jnp.ndarray = eqx.field(default_factory=lambda: jnp.asarray(0.0))
    quantum: jnp.ndarray = eqx.field(default_factory=lambda: jnp.asarray(0.0))  # sensor LSB, 0 = none
    u_init: jnp.ndarray = eqx.field(default_factory=lambda: jnp.asarray(0.0))
    eval_start: jnp.ndarray = eqx.field(default_factory=lambda: jnp.asarray(0.0))  # metrics count t_k >= this (s)
    key: jnp.ndarray = eqx.field(default_factory=lambda: jax.random.PRNGKey(0))

    def __check_init__(self):
        _parts(self.plant)
        ref = self.reference
        if not isinstance(ref, jax.core.Tracer):
            ref = np.asarray(ref)
            if ref.ndim < 1 or ref.shape[-1] < 2:
                raise ValueError(f"reference must be a record of at least 2 samples, got shape {ref.shape}")
            if not np.all(np.isfinite(ref)):
                raise ValueError("reference contains non-finite values")


# -- per-sample plant ------------------------------------------------------------


def _parts(model):
    """``(thermal or None, hysteresis)``: the model's per-sample stages (``plant_parts``: a hysteresis model, a `Cascade`)."""
    parts = getattr(model, "plant_parts", None)
    if parts is not None:
        return parts()
    raise TypeError(
        "closed-loop plant / compensator model must be a Cascade (thermal + hysteresis) or a hysteresis model "
        f"(EUPI, Preisach), got {type(model).__name__}"
    )


def plant_init(model, u_init):
    """State before the first sample: ``(theta, hysteresis state, fresh)`` for a plant resting at ``u_init``.

    ``theta(-1) = g u_init^2`` when the thermal init is ``"steady"``, else 0.  The
    hysteresis state is initialised lazily at the first sample (``fresh``) by the
    model's own ``initial_state`` rule applied to that sample's (effective) input,
    exactly as `Cascade.simulate` / the hysteresis model's ``simulate`` do.
    """
    thermal, hyst = _parts(model)
    u_init = _f64(u_init)
    theta = thermal.sample_start(u_init) if thermal is not None else jnp.zeros_like(u_init)
    placeholder = jax.tree.map(jnp.zeros_like, hyst.initial_state(hyst.u_ref))  # replaced at the first sample
    return theta, placeholder, jnp.asarray(True)


def plant_step(model, state, u, dt):
    """One sample of the plant: ``(state, U(k)) -> (state, y(k))`` (thermal ZOH step, then the hysteresis ``step``)."""
    theta, hstate, fresh = state
    thermal, hyst = _parts(model)
    if thermal is not None:
        theta, th = thermal.sample_step(theta, u, dt)
        x = model.drive_of(th)
    else:
        x = u
    hstate = jax.tree.map(lambda first, kept: jnp.where(fresh, first, kept), hyst.initial_state(x), hstate)
    hstate, y = hyst.step(hstate, x)
    return (theta, hstate, jnp.asarray(False)), y


def _rest(model, u_init, dt):
    """Plant state and output after resting one sample at ``u_init`` (the closed loop's y(0))."""
    return plant_step(model, plant_init(model, u_init), _f64(u_init), dt)


# -- the closed loop ---------------------------------------------------------------


def _scan_loop(loop: ClosedLoop, dt, record: bool):
    dt = _f64(dt)
    pid = loop.pid
    ref = _f64(loop.reference)
    n = ref.shape[0]
    noise = loop.noise_sd * jax.random.normal(loop.key, (n,), dtype=jnp.float64)
    pstate, y0 = _rest(loop.plant, loop.u_init, dt)
    comp = loop.compensator
    if comp is not None:
        H = comp.forward_model
        cstate, yhat0 = _rest(H, comp.to_forward_input(_f64(loop.u_init)), dt)
        u20 = jnp.clip(_f64(loop.u_init), pid.umin, pid.umax)
    else:
        cstate, yhat0, u20 = (), jnp.zeros(()), jnp.zeros(())
    zero = jnp.zeros(())
    # carry: plant state, y, I, D, previous measurement, compensator state, u2, yhat, accumulators
    # the drive's extremes over the whole record: fitted models are only trusted inside their training input range
    carry0 = (
        pstate,
        y0,
        zero,
        zero,
        y0,
        cstate,
        u20,
        yhat0,
        (zero, zero, zero, zero, zero, jnp.asarray(jnp.inf), jnp.asarray(-jnp.inf)),
    )

    def measure(y, nk):
        ym = y + nk
        q = loop.quantum
        return jnp.where(q > 0, jnp.round(ym / jnp.where(q > 0, q, 1.0)) * q, ym)

    def step(carry, xs):
        pst, y, integ, deriv, ym_prev, cst, u2, yhat, acc = carry
        r_k, n_k, t_k = xs
        ym = measure(y, n_k)
        e = r_k - ym
        if comp is not None:
            # the integrator must climb the forward model's slope: flip for a falling (length) output
            slope = float(comp.forward_model.hysteresis.orientation)
            u2 = jnp.clip(u2 + dt * comp.K * slope * (r_k - yhat), pid.umin, pid.umax)
            cst, yhat = plant_step(H, cst, comp.to_forward_input(u2), dt)
        p_term = pid.kp * e
        deriv = (pid.tf * deriv - pid.kd * (ym - ym_prev)) / (pid.tf + dt)
        integ_try = integ + pid.ki * dt * e
        raw_try = p_term + integ_try + deriv + u2
        if pid.anti_windup:
            block = ((raw_try > pid.umax) & (e > 0)) | ((raw_try < pid.umin) & (e < 0))
            integ = jnp.where(block, integ, integ_try)
        else:
            integ = integ_try
        u1 = p_term + integ + deriv
        raw = u1 + u2
        u = jnp.clip(raw, pid.umin, pid.umax)
        sat = (raw > pid.umax) | (raw < pid.umin)
        err = r_k - y  # true tracking error at sample k (eq. 8 uses y_d(k) - y(k))
        w = (t_k >= loop.eval_start - 0.5 * dt).astype(jnp.float64)  # metrics window
        a_abs, a_sq, a_max, a_sat, a_n, u_lo, u_hi = acc
        acc = (
            a_abs + w * jnp.abs(err),
            a_sq + w * err * err,
            jnp.maximum(a_max, w * jnp.abs(err)),
            a_sat + w * sat,
            a_n + w,
            jnp.minimum(u_lo, u),
            jnp.maximum(u_hi, u),
        )
        pst, y_next = plant_step(loop.plant, pst, u, dt)
        out = (
            {
                "y": y,
                "y_meas": ym,
                "reference": r_k,
                "error": err,
                "u": u,
                "u1": u1,
                "u2": u2,
                "integral": integ,
                "saturated": sat,
            }
            if record
            else None
        )
        return (pst, y_next, integ, deriv, ym, cst, u2, yhat, acc), out

    times = jnp.arange(n) * dt
    carry, out = jax.lax.scan(step, carry0, (ref, noise, times))
    a_abs, a_sq, a_max, a_sat, a_n, u_lo, u_hi = carry[-1]
    a_n = jnp.maximum(a_n, 1.0)  # an empty window gives zeros rather than NaN
    metrics = {
        "e_mean_mm": a_abs / a_n,
        "rmse_mm": jnp.sqrt(a_sq / a_n),
        "max_abs_error_mm": a_max,
        "saturated_fraction": a_sat / a_n,
        "u_min_V": u_lo,
        "u_max_V": u_hi,
    }
    return metrics, out


@eqx.filter_jit
def _simulate(loop, dt):
    metrics, out = _scan_loop(loop, dt, True)
    out["time_s"] = jnp.arange(loop.reference.shape[0]) * dt
    return metrics, out


@eqx.filter_jit
def _metrics(loop, dt):
    return _scan_loop(loop, dt, False)[0]


def _check_dt(dt):
    """``dt`` as a float64 scalar: checked in Python when concrete (`check_sample_time`), by `eqx.error_if` when traced
    (a user's own `jax.jit` / `jax.grad` around the closed loop; a Python check of a tracer raised there)."""
    check_sample_time(dt)
    dt = jnp.asarray(dt, dtype=jnp.float64)
    return eqx.error_if(dt, ~(dt > 0), "dt must be > 0") if isinstance(dt, jax.core.Tracer) else dt


def simulate_closed_loop(loop: ClosedLoop, dt: float) -> tuple[dict[str, Any], dict[str, Any]]:
    """Run one configuration; returns ``(metrics, trajectories)`` (dicts of arrays).

    Trajectories: ``time_s, reference, y, y_meas, error, u, u1 (PID), u2 (I-I), integral, saturated``.
    Metrics: ``e_mean_mm`` (eq. 8), ``rmse_mm``, ``max_abs_error_mm``, ``saturated_fraction`` (over the
    evaluation window), ``u_min_V`` / ``u_max_V`` (drive extremes over the whole record).
    """
    if np.ndim(loop.reference) != 1:
        raise ValueError(f"reference must be 1-D for a single run, got shape {np.shape(loop.reference)}; use smafl_jax.sweep")
    return _simulate(scalar_leaves_as_arrays(loop), _check_dt(dt))


def closed_loop_metrics(loop: ClosedLoop, dt: float) -> dict[str, Any]:
    """Metrics only (accumulated inside the scan, no trajectories stored): what sweeps use."""
    return _metrics(scalar_leaves_as_arrays(loop), _check_dt(dt))  # a float set by tree_at would compile per value


@eqx.filter_jit
def _open_loop(model, u, dt):
    """The plant's output for the drive ``u`` from rest at ``u[0]``, by the closed loop's own plant step."""

    def step(state, uk):
        return plant_step(model, state, uk, dt)

    return jax.lax.scan(step, plant_init(model, u[0]), u)[1]


#: Samples per phase of `reachable_output`'s slow cycle; each phase lasts 5 thermal time constants (99.3 % settled).
REACH_SAMPLES = 400


def reachable_output(plant: Any, umax: float, umin: float = 0.0) -> tuple[float, float]:
    """``(lowest, highest)`` output of ``plant`` with its drive limited to ``[umin, umax]``.

    Taken along a slow full cycle from rest at ``umin``: hold, ramp to ``umax``, hold, ramp back, hold, each phase five
    thermal time constants long (a hysteresis model is rate independent; the Joule lag's ZOH step is exact at any
    sample time).  A lagged plant driven within the limits keeps its thermal state inside the range of the settled
    ones, so on a monotone model the cycle's ends bound what any drive reaches; a reference outside this range cannot
    be tracked, the drive saturates there.
    """
    thermal, _ = _parts(plant)
    dt = 5.0 / (float(thermal.k1) * REACH_SAMPLES) if thermal is not None else 1.0
    ramp = np.linspace(umin, umax, REACH_SAMPLES)
    hold_lo, hold_hi = np.full(REACH_SAMPLES, float(umin)), np.full(REACH_SAMPLES, float(umax))
    u = np.concatenate([hold_lo, ramp, hold_hi, ramp[::-1], hold_lo])
    y = np.asarray(_open_loop(plant, jnp.asarray(u), jnp.asarray(dt, dtype=jnp.float64)))
    return float(np.min(y)), float(np.max(y))


# -- references -----------------------------------------------------------------------


def sine_reference(
    duration: float,
    dt: float,
    amplitude: float = 1.0,
    omega: float = 3 * np.pi / 10,
    phase: float = np.pi / 2,
    offset: float = 1.5,
) -> np.ndarray:
    """Paper's sine ``amplitude sin(omega t + phase) + offset`` (mm), sampled at ``t = k dt``."""
    t = np.arange(int(round(duration / dt))) * dt
    return amplitude * np.sin(omega * t + phase) + offset


def step_reference(duration: float, dt: float, height: float = 2.5, t_step: float = 0.0, base: float = 0.0) -> np.ndarray:
    """Step of ``height`` mm at ``t_step`` s (paper: 2.5 mm from t = 0)."""
    t = np.arange(int(round(duration / dt))) * dt
    return np.where(t >= t_step, base + height, base)
