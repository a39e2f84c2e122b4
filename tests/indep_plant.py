"""Independent test plant: a randomised SMA/fishing-line actuator simulator in plain numpy.

Why: a method checked only on records from its own model classes looks perfect and fails
elsewhere.  This module is a second, independent implementation of the paper's cascade
(drive voltage -> Joule heating -> first-order thermal lag -> play-operator hysteresis ->
sensor) with every structural choice drawn at random from a seed and returned as ``truth``.
It shares NO code with smafl_jax and imports neither jax nor scipy (a test parses this file).
Every recurrence runs one sample at a time in a plain Python loop.

Public API
----------
make_drive(family, duration_s, dt, rng, u_max) -> u (>= 0, volts)
random_truth(rng, **overrides) -> truth (JSON-serialisable dict)
simulate(truth, u, dt) -> dict(y, y_clean, theta, x_h, T, h, u_applied, extra)
make_record(seed, *, effect=None, variant=None, drive=None, rate_hz=None, minutes=None,
            start=None, orientation=None, noise=None, excursion=False) -> record dict
write_csv(path, rec) -> writes PATH (time_s, voltage_V, displacement_mm [+ extra columns])
                       and NAME.truth.json beside it (never NAME.json: the toolkit reads that as a sidecar)

Conventions
-----------
Hold-out: the last 30 % of a record (samples >= ``heldout_start``) is held out.  Its drive
voltage is clipped into the [min, max] voltage range of the first 70 %; the hysteresis input
(thermal state) of the clean plant is also checked against the first 70 % and the drive is
redrawn (then, as a last resort, shrunk) until it stays inside (recorded in ``meta``).
``excursion=True`` then places a stretch in the held-out part whose drive exceeds the trained
voltage range by a stated amount (``excursion_span``), after which the drive returns in range.

Play operator (PAPER.md eq. 1), threshold r >= 0, tilt alpha > 0:
    F(k) = max(x(k) - r, min(alpha * (x(k) + r), F(k - 1)));  alpha = 1 is the symmetric operator.
Hysteresis output (motion, mm): h = G x + sum_i w_i F_i + c2 x^2 [+ c3 x^3].
"""

from __future__ import annotations

import copy
import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np

FAMILIES = ("staircase", "pwm", "multisine", "chirp", "steps", "triangle", "random_levels")
STARTS = ("cold", "warm", "mid")
ORIENTATIONS = ("displacement", "length")
NOISE_KINDS = ("fixed", "fraction")
THERMAL_SCHEMES = ("zoh_current", "zoh_previous", "euler", "rk4")
HYST_INPUTS = ("effective_voltage", "temperature")
#: The cells of issue 18's robustness matrix (experiments/base_fit_before_after.py, matrix_branch_coverage.py):
#: keywords of `make_record` by cell name.
MATRIX_CELLS = {
    "multisine, cold, 25 Hz": dict(drive="multisine", rate_hz=25, start="cold"),
    "PWM, cold, 25 Hz": dict(drive="pwm", rate_hz=25, start="cold"),
    "staircase, warm, 10 Hz": dict(drive="staircase", rate_hz=10, start="warm"),
    "PWM, length sensor, 25 Hz": dict(drive="pwm", rate_hz=25, start="cold", orientation="length"),
    "multisine, half-warm, 10 Hz": dict(drive="multisine", rate_hz=10, start="mid"),
    # session 28: random multi-level drives with ramps and holds (what issue 13 says the judges' simulator uses)
    "random_levels, cold, 20 Hz, length sensor": dict(drive="random_levels", rate_hz=20, start="cold", orientation="length"),
}
MEMORY_KINDS = ("zero", "from_above", "random")
HELDOUT_FRACTION = 0.3
FIXED_NOISE_SD = 0.005  # mm
ABS_ZERO = 273.15

# Effects the toolkit's catalogue names, each with at least two physically different implementations.
EFFECTS: dict[str, tuple[str, ...]] = {
    "resistance_tc": ("linear", "quadratic"),
    "nonlinear_cooling": ("convective", "radiative"),
    "asymmetric_cooling": ("constant_ratio", "latent_heat"),
    "ambient_drift": ("linear_ramp", "room_warming"),
    "creep": ("kelvin_voigt", "spectrum"),
    "delay": ("integer", "fractional"),
    "rate_dependence": ("threshold_widening", "viscous"),
    "sensor_lag": ("first_order", "second_order"),
    "output_saturation": ("tanh", "soft_clip"),
    "strain_accumulation": ("threshold_linear", "arrhenius_saturating"),
}
# Effects in no catalogue: the right answer of a diagnosis is "unexplained".
UNCATALOGUED: dict[str, tuple[str, ...]] = {
    "extra_column": ("humidity", "supply_voltage"),
    "periodic_disturbance": ("sinusoid", "square_load"),
    "gain_drift": ("linear", "warmup"),
}
ALL_EFFECTS = {**EFFECTS, **UNCATALOGUED}
EFFECT_MIN_SNR = 5.0  # an effect must change the clean output by >= 5x the noise RMS
_SENSOR_FULL_SCALES = (2.0, 5.0, 10.0, 20.0, 25.0, 50.0, 100.0, 200.0, 500.0)


def _logu(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _py(obj):
    """Plain-Python (JSON-serialisable) copy of nested numpy values."""
    if isinstance(obj, dict):
        return {str(k): _py(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_py(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return [_py(v) for v in obj.tolist()]
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


# ----------------------------------------------------------------------------------------------
# Drives
# ----------------------------------------------------------------------------------------------
def _segments(n: int, dt: float, rng: np.random.Generator, draw) -> np.ndarray:
    """Fill n samples with consecutive pieces; draw(prev_end_value) -> array of >= 1 samples."""
    out = np.empty(n)
    k, last = 0, 0.0
    while k < n:
        piece = np.asarray(draw(last), dtype=float)
        m = min(len(piece), n - k)
        out[k : k + m] = piece[:m]
        k += m
        last = float(piece[-1])
    return out


def _smooth_unit(n: int, dt: float, rng: np.random.Generator, p_lo: float, p_hi: float, n_comp: int = 4) -> np.ndarray:
    """Slow random signal in [-1, 1]: a few sinusoids with random periods in [p_lo, p_hi] s."""
    t = np.arange(n) * dt
    s = np.zeros(n)
    for _ in range(n_comp):
        s += rng.normal() * np.sin(2 * np.pi * t / _logu(rng, p_lo, p_hi) + rng.uniform(0, 2 * np.pi))
    return s / max(float(np.max(np.abs(s))), 1e-12)


def make_drive(family: str, duration_s: float, dt: float, rng: np.random.Generator, u_max: float) -> np.ndarray:
    """Positive drive voltage (0..u_max V) of one family, ``round(duration_s / dt)`` samples."""
    n = int(round(duration_s / dt))
    if n < 2:
        raise ValueError(f"duration {duration_s} s at dt {dt} s gives fewer than 2 samples")
    t = np.arange(n) * dt
    hold = lambda lo, hi: max(1, int(round(_logu(rng, lo, hi) / dt)))
    if family == "staircase":
        u = _segments(n, dt, rng, lambda _: np.full(hold(5.0, 180.0), rng.uniform(0.0, u_max)))
    elif family == "pwm":
        level = rng.uniform(2.0, min(6.0, u_max))
        period = max(_logu(rng, 0.5, 20.0), 4 * dt)
        duty = np.clip(0.5 + 0.45 * _smooth_unit(n, dt, rng, duration_s / 4, 2 * duration_s, 3), 0.03, 0.97)
        u = level * (((t / period) % 1.0) < duty)
    elif family == "multisine":
        m = int(rng.integers(3, 9))
        s = np.zeros(n)
        for _ in range(m):
            f = _logu(rng, 5e-4, min(0.1, 0.2 / dt))  # thermal corner k1/2pi is 0.003..0.03 Hz
            s += rng.uniform(0.2, 1.0) * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
        s /= max(float(np.max(np.abs(s))), 1e-12)
        off = rng.uniform(0.3, 0.6) * u_max
        u = np.clip(off + rng.uniform(0.6, 1.2) * max(off, u_max - off) * s, 0.0, u_max)
    elif family == "chirp":
        f0, f1 = _logu(rng, 5e-4, 3e-3), _logu(rng, 0.02, min(0.3, 0.1 / dt))
        if rng.random() < 0.5:
            f0, f1 = f1, f0
        phase = 2 * np.pi * f0 * duration_s / math.log(f1 / f0) * (np.exp(t / duration_s * math.log(f1 / f0)) - 1.0)
        mid = rng.uniform(0.35, 0.65) * u_max
        amp = min(mid, u_max - mid) * rng.uniform(0.6, 1.0)
        u = mid + amp * np.sin(phase + rng.uniform(0, 2 * np.pi))
    elif family == "steps":
        base = 0.0 if rng.random() < 0.5 else rng.uniform(0.0, 0.3 * u_max)

        def step(_):
            return np.concatenate([np.full(hold(5.0, 120.0), rng.uniform(base, u_max)), np.full(hold(5.0, 120.0), base)])

        u = _segments(n, dt, rng, step)
    elif family == "triangle":
        state = {"up": True}

        def sweep(last):
            nxt = rng.uniform(last, u_max) if state["up"] else rng.uniform(0.0, last)
            if rng.random() < 0.25:  # now and then a full sweep to the end of the range
                nxt = u_max if state["up"] else 0.0
            state["up"] = not state["up"]
            m = max(2, int(round(abs(nxt - last) / _logu(rng, 0.005, 0.3) / dt)))
            return np.linspace(last, nxt, m + 1)[1:]

        u = _segments(n, dt, rng, sweep)
    elif family == "random_levels":

        def lev(last):
            nxt = rng.uniform(0.0, u_max)
            ramp = np.linspace(last, nxt, hold(1.0, 60.0) + 1)[1:]
            return np.concatenate([ramp, np.full(hold(2.0, 120.0), nxt)])

        u = _segments(n, dt, rng, lev)
    else:
        raise ValueError(f"unknown drive family {family!r}; choose one of {FAMILIES}")
    return np.clip(np.asarray(u, dtype=float), 0.0, u_max)


# ----------------------------------------------------------------------------------------------
# Structure
# ----------------------------------------------------------------------------------------------
def _draw_effect(name: str, variant: str, rng: np.random.Generator, tr: dict) -> dict:
    """Base parameters of one effect; ``scale`` lists the keys multiplied by the strength, ``cap`` its maximum."""
    rng_mm = tr["hysteresis"]["range_mm"]
    trise = tr["thermal"]["trise_K"]
    x_max = tr["hysteresis"]["x_max"]
    sgn = 1.0 if rng.random() < 0.5 else -1.0
    p: dict = {}
    if name == "resistance_tc":
        # A falling resistance raises the Joule power (voltage drive): too much of it runs away thermally.
        # The cap keeps R >= 0.6 R0 and dT * R(dT) increasing up to 2.5 trise, so every drive has one steady state.
        if variant == "linear":  # R = R0 (1 + a dT)
            p = {"a1_per_K": (rng.uniform(0.1, 0.4) if sgn > 0 else -rng.uniform(0.03, 0.12)) / trise}
            scale = ["a1_per_K"]
        else:  # R = R0 (1 + a1 dT + a2 dT^2)
            p = {"a1_per_K": rng.uniform(-0.05, 0.15) / trise,
                 "a2_per_K2": (rng.uniform(0.05, 0.3) if sgn > 0 else -rng.uniform(0.01, 0.04)) / trise**2}  # fmt: skip
            scale = ["a1_per_K", "a2_per_K2"]
        cap = _resistance_cap(p, trise)
    elif name == "nonlinear_cooling":
        if variant == "convective":  # k1 [(1 - c) + c (|dT| / dT_ref)^0.25] dT
            p = {"c": rng.uniform(0.2, 0.6), "dT_ref_K": 0.5 * trise, "exponent": 0.25}
            cap = 0.95 / p["c"]
        else:  # k1 [(1 - c) dT + c (T^4 - Ta^4) / (4 Ta^3)]
            p = {"c": rng.uniform(0.3, 0.9)}
            cap = 1.0 / p["c"]
        scale = ["c"]
    elif name == "asymmetric_cooling":
        if variant == "constant_ratio":  # cooling rate = ratio * heating-law rate
            p = {"log_ratio": sgn * rng.uniform(0.3, 0.9)}
            cap = 1.6 / abs(p["log_ratio"])
            scale = ["log_ratio"]
        else:  # on cooling only: heat capacity 1 + L exp(-((dT - dT_tr) / w)^2)
            p = {"L": rng.uniform(1.0, 4.0), "dT_tr_K": rng.uniform(0.3, 0.7) * trise, "w_K": rng.uniform(0.1, 0.25) * trise}
            cap = 20.0 / p["L"]
            scale = ["L"]
    elif name == "ambient_drift":
        if variant == "linear_ramp":
            p = {"rate_K_per_h": sgn * rng.uniform(2.0, 8.0)}
            cap = 40.0 / abs(p["rate_K_per_h"])
            scale = ["rate_K_per_h"]
        else:  # slow exponential warming of the room
            p = {"D_K": rng.uniform(2.0, 6.0), "tau_s": rng.uniform(600.0, 2400.0)}
            cap = 30.0 / p["D_K"]
            scale = ["D_K"]
    elif name == "creep":
        if variant == "kelvin_voigt":
            p = {"kappa": [sgn * rng.uniform(0.03, 0.15)], "tau_s": [_logu(rng, 20.0, 600.0)]}
        else:
            m = int(rng.integers(3, 6))
            taus = np.sort(np.exp(rng.uniform(math.log(5.0), math.log(3000.0), m)))
            w = rng.dirichlet(np.ones(m)) * rng.uniform(0.05, 0.2) * sgn
            p = {"kappa": w.tolist(), "tau_s": taus.tolist()}
        p["initial_fraction"] = rng.uniform(0.0, 1.0)
        cap = 1.0 / sum(abs(k) for k in p["kappa"])
        scale = ["kappa"]
    elif name == "delay":
        if variant == "integer":  # transport delay of the drive, whole samples
            p = {"delay_s": rng.uniform(0.5, 4.0)}
        else:  # delay of the measured output, a non-integer number of samples (linear interpolation)
            p = {"delay_s": rng.uniform(0.5, 4.0), "fraction": rng.uniform(0.2, 0.8)}
        cap = 20.0 / p["delay_s"]
        scale = ["delay_s"]
    elif name == "rate_dependence":
        if variant == "threshold_widening":  # r_eff = r (1 + beta |dx/dt|_filtered / x_max)
            p = {"beta_s": rng.uniform(2.0, 10.0), "tau_f_s": rng.uniform(0.5, 5.0)}
            cap = 500.0 / p["beta_s"]
            scale = ["beta_s"]
        else:  # h += eta * dx/dt filtered
            p = {"eta": sgn * rng.uniform(0.3, 1.0) * rng_mm / x_max * rng.uniform(1.0, 10.0), "tau_f_s": rng.uniform(0.5, 5.0)}
            cap = 100.0
            scale = ["eta"]
    elif name == "sensor_lag":
        p = {"tau_s": rng.uniform(0.5, 5.0)}  # second_order: two equal first-order poles (critically damped)
        cap = 60.0 / p["tau_s"]
        scale = ["tau_s"]
    elif name == "output_saturation":
        if variant == "tanh":  # h -> tanh(h / S) S
            p = {"inv_S_per_mm": 1.0 / (rng_mm * rng.uniform(0.8, 2.0))}
            cap = 4.0 / rng_mm / p["inv_S_per_mm"]
            scale = ["inv_S_per_mm"]
        else:  # smooth clip at (1 - depth) of the range, knee width w
            p = {"depth": rng.uniform(0.05, 0.35), "knee_mm": rng.uniform(0.03, 0.1) * rng_mm}
            cap = 0.8 / p["depth"]
            scale = ["depth"]
    elif name == "strain_accumulation":
        # theta_ref (set by make_record from the record: the highest trained normalised temperature) keeps
        # "hot" relative to what the record reaches.
        if variant == "threshold_linear":  # ds/dt = gamma max(0, theta_n / theta_ref - th_fraction)
            p = {"gamma_mm_per_s": sgn * rng.uniform(0.05, 0.3) * rng_mm / 600.0, "th_fraction": rng.uniform(0.3, 0.7)}
        else:  # ds/dt = gamma exp(E (theta_n / theta_ref - 1)) (1 - s / s_max)
            smax = sgn * rng.uniform(0.1, 0.5) * rng_mm
            p = {"gamma_mm_per_s": smax / rng.uniform(200.0, 2000.0), "E": rng.uniform(3.0, 8.0), "s_max_mm": smax}
        p["theta_ref"] = 1.0
        cap = 100.0
        scale = ["gamma_mm_per_s"]
    elif name == "extra_column":
        if variant == "humidity":  # nylon swells with humidity; humidity_pct written to the CSV
            p = {
                "coef_mm_per_pct": sgn * rng.uniform(0.002, 0.01) * rng_mm,
                "h_mean": rng.uniform(35.0, 60.0),
                "h_amp": rng.uniform(5.0, 15.0),
            }
            p["column"] = "humidity_pct"
            cap = 50.0
            scale = ["coef_mm_per_pct"]
        else:  # the applied voltage follows a varying supply; supply_V written to the CSV
            p = {"v_nom": float(rng.choice([9.0, 12.0, 15.0])), "depth": rng.uniform(0.02, 0.08), "column": "supply_V"}
            cap = 0.3 / p["depth"]
            scale = ["depth"]
        p["signal_seed"] = int(rng.integers(0, 2**31 - 1))
    elif name == "periodic_disturbance":
        if variant == "sinusoid":  # additive mechanical vibration / periodic load
            p = {"A_mm": rng.uniform(0.02, 0.1) * rng_mm, "f_hz": _logu(rng, 0.002, 0.2), "phase": rng.uniform(0, 2 * np.pi)}
            cap = 20.0
            scale = ["A_mm"]
        else:  # a cycling load changes the stroke: h (1 + m sq(t))
            p = {
                "m": rng.uniform(0.03, 0.1),
                "period_s": _logu(rng, 30.0, 600.0),
                "phase": rng.uniform(0, 1),
                "edge_s": rng.uniform(1.0, 10.0),
            }
            cap = 0.5 / p["m"]
            scale = ["m"]
    elif name == "gain_drift":
        if variant == "linear":
            p = {"g_per_h": sgn * rng.uniform(0.02, 0.1)}
            cap = 0.5 / abs(p["g_per_h"])
            scale = ["g_per_h"]
        else:
            p = {"g": sgn * rng.uniform(0.02, 0.08), "tau_s": rng.uniform(300.0, 1800.0)}
            cap = 0.3 / abs(p["g"])
            scale = ["g"]
    else:
        raise ValueError(f"unknown effect {name!r}; choose one of {sorted(ALL_EFFECTS)}")
    return {"name": name, "variant": variant, "params": p, "scale_keys": scale, "strength": 1.0, "max_strength": float(cap)}


def _resistance_cap(p: dict, trise: float) -> float:
    """Largest strength with R >= 0.6 R0 and dT * R(dT) increasing on 0 .. 2.5 trise (bisection)."""
    d = np.linspace(0.0, 2.5 * trise, 501)

    def ok(s):
        rel = 1.0 + s * p["a1_per_K"] * d + s * p.get("a2_per_K2", 0.0) * d * d
        return bool(np.all(rel >= 0.6) and np.all(np.diff(d * rel) > 0))

    lo, hi = 0.0, 1.0
    while ok(hi) and hi < 1e3:
        lo, hi = hi, 2.0 * hi
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return min(lo, 1.0 / (abs(p["a1_per_K"]) * trise + abs(p.get("a2_per_K2", 0.0)) * trise**2) * 1.0)


def _hyst_raw(hy: dict, x: np.ndarray) -> np.ndarray:
    """Unscaled-gain hysteresis from the zero state, for normalisation only."""
    f = [0.0] * len(hy["r"])
    out = np.empty(len(x))
    for k, xk in enumerate(x):
        acc = hy["G"] * xk + sum(c * xk ** (i + 2) for i, c in enumerate(hy["poly"]))
        for i, (r, a, w) in enumerate(zip(hy["r"], hy["alpha"], hy["w"])):
            f[i] = max(xk - r, min(a * (xk + r), f[i]))
            acc += w * f[i]
        out[k] = acc
    return out


def random_truth(rng: np.random.Generator, **overrides) -> dict:
    """Draw a full plant structure.  Overrides: u_max, k1, trise_K, ambient_C, scheme, hyst_input, start,
    memory, n_ops, range_mm, orientation, noise ('fixed' | 'fraction' | SD in mm), effect, variant."""
    allowed = {"u_max", "k1", "trise_K", "ambient_C", "scheme", "hyst_input", "start", "memory", "n_ops", "range_mm",
               "orientation", "noise", "effect", "variant"}  # fmt: skip
    bad = set(overrides) - allowed
    if bad:
        raise ValueError(f"unknown override(s) {sorted(bad)}; allowed {sorted(allowed)}")
    o = {k: v for k, v in overrides.items() if v is not None}
    # Draw every value in a fixed order so that an override does not shift the others.
    d = {
        "u_max": rng.uniform(4.0, 8.0),
        "k1": _logu(rng, 0.02, 0.2),
        "trise_K": rng.uniform(30.0, 120.0),
        "ambient_C": rng.uniform(18.0, 30.0),
        "scheme": str(rng.choice(THERMAL_SCHEMES)),
        "rk4_substeps": int(rng.integers(2, 7)),
        "rk4_sample": str(rng.choice(["current", "previous"])),
        "hyst_input": str(rng.choice(HYST_INPUTS)),
        "start": str(rng.choice(STARTS)),
        "mid_fraction": rng.uniform(0.2, 0.8),
        "memory": str(rng.choice(MEMORY_KINDS)),
        "n_ops": int(rng.integers(3, 13)),
        "range_mm": rng.uniform(1.5, 7.0),
        "orientation": str(rng.choice(ORIENTATIONS)),
        "offset_disp": rng.uniform(-0.5, 0.5),
        "offset_len": rng.uniform(10.0, 50.0),
        "noise": str(rng.choice(NOISE_KINDS)),
        "noise_fraction": _logu(rng, 1e-3, 1.5e-2),
        "noise_seed": int(rng.integers(0, 2**31 - 1)),
        "sensor_pos": rng.uniform(0.1, 0.9),
    }
    d.update(o)
    u_max, k1, trise = float(d["u_max"]), float(d["k1"]), float(d["trise_K"])
    x_max = u_max if d["hyst_input"] == "effective_voltage" else 1.0
    # Hysteresis: 1.. symmetric + 1.. unparallel operators, thresholds continuous random (no grid).
    n_ops = int(d["n_ops"])
    n_sym = int(rng.integers(1, n_ops))
    r = (rng.uniform(0.0, 0.6, n_ops) * x_max).tolist()
    alpha = [1.0] * n_sym + [_logu(rng, 0.3, 3.0) for _ in range(n_ops - n_sym)]
    w = rng.lognormal(0.0, 0.7, n_ops)
    w = (w / w.sum()).tolist()
    order = int(rng.integers(2, 4))
    poly = [rng.uniform(-0.3, 0.3) / x_max]
    if order == 3:
        poly.append(rng.uniform(-0.2, 0.2) / x_max**2)
    hy = {"input": d["hyst_input"], "x_max": x_max, "n_sym": n_sym, "r": r, "alpha": alpha, "w": w,
          "G": rng.uniform(0.0, 0.5), "poly": poly, "range_mm": float(d["range_mm"])}  # fmt: skip
    xr = np.concatenate([np.linspace(0, x_max, 300), np.linspace(x_max, 0, 300)])
    raw = _hyst_raw(hy, xr)
    s = hy["range_mm"] / float(np.ptp(raw))
    hy["G"] *= s
    hy["w"] = [v * s for v in hy["w"]]
    hy["poly"] = [v * s for v in hy["poly"]]
    hy["memory"] = {"kind": d["memory"], "fractions": rng.uniform(0.0, 1.0, n_ops).tolist()}
    orient = d["orientation"]
    noise = d["noise"]
    if isinstance(noise, int | float):
        noise_d = {"kind": "given", "sd": float(noise)}
    elif noise == "fixed":
        noise_d = {"kind": "fixed", "sd": FIXED_NOISE_SD}
    elif noise == "fraction":
        noise_d = {"kind": "fraction", "fraction": float(d["noise_fraction"]), "sd": float(d["noise_fraction"]) * hy["range_mm"]}
    else:
        raise ValueError(f"noise must be one of {NOISE_KINDS} or an SD in mm, not {noise!r}")
    noise_d["seed"] = d["noise_seed"]
    truth = {
        "drive": {"u_max": u_max},
        "thermal": {
            "k1": k1,
            "k2": k1 * trise / u_max**2,
            "trise_K": trise,
            "ambient_C": float(d["ambient_C"]),
            "scheme": d["scheme"],
            "rk4_substeps": d["rk4_substeps"],
            "rk4_sample": d["rk4_sample"],
            "start": d["start"],
            "mid_fraction": d["mid_fraction"],
        },
        "hysteresis": hy,
        "sensor": {
            "orientation": orient,
            "offset_mm": float(d["offset_disp"] if orient == "displacement" else d["offset_len"]),
            "bits": 16,
            "position": d["sensor_pos"],
        },
        "noise": noise_d,
        "effect": None,
    }
    for key, allowed_v in (("scheme", THERMAL_SCHEMES), ("hyst_input", HYST_INPUTS), ("start", STARTS),
                           ("memory", MEMORY_KINDS), ("orientation", ORIENTATIONS)):  # fmt: skip
        if d[key] not in allowed_v:
            raise ValueError(f"{key} must be one of {allowed_v}, not {d[key]!r}")
    eff_rng = np.random.default_rng(int(rng.integers(0, 2**63 - 1)))
    if d.get("effect"):
        name = d["effect"]
        if name not in ALL_EFFECTS:
            raise ValueError(f"unknown effect {name!r}; choose one of {sorted(ALL_EFFECTS)}")
        var = d.get("variant") or str(eff_rng.choice(ALL_EFFECTS[name]))
        if var not in ALL_EFFECTS[name]:
            raise ValueError(f"effect {name!r} has variants {ALL_EFFECTS[name]}, not {var!r}")
        truth["effect"] = _draw_effect(name, var, eff_rng, truth)
    return _py(truth)


def _effect_params(eff: dict | None) -> dict:
    """Parameters with the strength applied to the scaled keys."""
    if not eff:
        return {}
    p = dict(eff["params"])
    s = float(eff.get("strength", 1.0))
    for k in eff.get("scale_keys", []):
        p[k] = [v * s for v in p[k]] if isinstance(p[k], list) else p[k] * s
    return p


# ----------------------------------------------------------------------------------------------
# Simulation
# ----------------------------------------------------------------------------------------------
def _exogenous(truth: dict, n: int, dt: float) -> dict:
    """Recorded extra signals (humidity, supply voltage) of the extra-column effect."""
    eff = truth.get("effect") or {}
    if eff.get("name") != "extra_column":
        return {}
    p = _effect_params(eff)
    r = np.random.default_rng(p["signal_seed"])
    dur = n * dt
    if eff["variant"] == "humidity":
        h = p["h_mean"] + p["h_amp"] * _smooth_unit(n, dt, r, max(dur / 6, 60.0), max(2 * dur, 120.0), 4)
        return {p["column"]: np.round(h, 1)}  # a humidity sensor reports 0.1 %
    sag = _smooth_unit(n, dt, r, max(dur / 8, 30.0), max(dur, 60.0), 4)
    steps = np.cumsum(np.where(r.random(n) < dt / 300.0, r.normal(0, 0.5, n), 0.0))  # load switching on the supply rail
    steps = steps - steps.mean()
    v = p["v_nom"] * (1.0 + p["depth"] * (sag + 0.5 * steps / max(float(np.max(np.abs(steps))), 1.0)))
    return {p["column"]: np.round(v, 3)}


def _thermal_ab(T: float, ta: float, usq: float, th: dict, eff_name: str | None, var: str | None, p: dict):
    """dT/dt = g (-a (T - ta) + b) with the effect's a(T), b(T), g(T, sign); returns (a, b, g)."""
    k1, k2, ta0 = th["k1"], th["k2"], th["ambient_C"]
    dT = T - ta
    a = k1
    if eff_name == "nonlinear_cooling":
        c = p["c"]
        if var == "convective":
            a = k1 * ((1 - c) + c * (abs(dT) / p["dT_ref_K"]) ** p["exponent"])
        elif abs(dT) > 1e-9:
            tk, tak = T + ABS_ZERO, ta + ABS_ZERO
            a = k1 * ((1 - c) + c * (tk**4 - tak**4) / (4 * tak**3) / dT)
    rel_r = 1.0
    if eff_name == "resistance_tc":
        d0 = T - ta0
        rel_r = 1.0 + p["a1_per_K"] * d0 + p.get("a2_per_K2", 0.0) * d0 * d0
        rel_r = max(rel_r, 0.05)
    b = k2 * usq / rel_r
    g = 1.0
    if eff_name == "asymmetric_cooling" and -a * dT + b < 0:
        if var == "constant_ratio":
            g = math.exp(p["log_ratio"])
        else:
            g = 1.0 / (1.0 + p["L"] * math.exp(-((((T - ta0) - p["dT_tr_K"]) / p["w_K"]) ** 2)))
    return a, b, g


def _steady_T(truth: dict, usq: float) -> float:
    """Steady temperature at a constant squared drive (bisection; the plant's own heat balance)."""
    th = truth["thermal"]
    eff = truth.get("effect") or {}
    name, var, p = eff.get("name"), eff.get("variant"), _effect_params(eff)
    ta = th["ambient_C"]
    # Relax the heat balance from ambient: reaches the lowest stable equilibrium, the one a real warm-up reaches.
    T, h = ta, 0.3 / th["k1"]
    for _ in range(4000):
        a, b, _ = _thermal_ab(T, ta, usq, th, name, var, p)
        step = h * (-a * (T - ta) + b)
        T += step
        if abs(step) < 1e-10 * (1.0 + abs(T)):
            break
    return T


def _x_of_T(T: float, truth: dict) -> float:
    th, hy = truth["thermal"], truth["hysteresis"]
    theta = T - th["ambient_C"]
    if hy["input"] == "effective_voltage":
        return math.sqrt(max(theta, 0.0) * th["k1"] / th["k2"])
    return theta / th["trise_K"]


def _thermal_stage(truth: dict, u: np.ndarray, dt: float) -> dict:
    th = truth["thermal"]
    eff = truth.get("effect") or {}
    name, var, p = eff.get("name"), eff.get("variant"), _effect_params(eff)
    n = len(u)
    t = np.arange(n) * dt
    ta0 = th["ambient_C"]
    if name == "ambient_drift":
        ta = ta0 + (p["rate_K_per_h"] * t / 3600.0 if var == "linear_ramp" else p["D_K"] * (1.0 - np.exp(-t / p["tau_s"])))
    else:
        ta = np.full(n, ta0)
    ua = np.array(u, dtype=float)
    extra = _exogenous(truth, n, dt)
    if name == "extra_column" and var == "supply_voltage":
        ua = ua * extra[p["column"]] / p["v_nom"]
    start = th["start"]
    n_first = max(1, min(n, int(round(1.0 / th["k1"] / dt))))
    u_first = math.sqrt(float(np.mean(ua[:n_first] ** 2)))  # "U(0)" = RMS over the first time constant
    if name == "delay" and var == "integer":
        nd = max(1, int(round(p["delay_s"] / dt)))
        pre = u_first if start == "warm" else 0.0
        ua = np.concatenate([np.full(min(nd, n), pre), ua[: max(n - nd, 0)]])
    if start == "cold":
        T0 = ta0
    elif start == "warm":
        T0 = _steady_T(truth, u_first**2)
    else:
        T0 = ta0 + th["mid_fraction"] * (_steady_T(truth, truth["drive"]["u_max"] ** 2) - ta0)
    scheme = th["scheme"]
    T = np.empty(n)
    T[0] = T0
    Tk = T0
    for k in range(1, n):
        if scheme in ("zoh_current", "zoh_previous"):
            usq = (ua[k] if scheme == "zoh_current" else ua[k - 1]) ** 2
            tam = 0.5 * (ta[k] + ta[k - 1])
            a, b, g = _thermal_ab(Tk, tam, usq, th, name, var, p)
            ae = a * g
            ss = tam + b / a
            Tk = ss + (Tk - ss) * math.exp(-ae * dt)
        elif scheme == "euler":
            a, b, g = _thermal_ab(Tk, ta[k - 1], ua[k - 1] ** 2, th, name, var, p)
            Tk = Tk + dt * g * (-a * (Tk - ta[k - 1]) + b)
        else:  # RK4 with sub-steps, drive held at one sample
            m = th["rk4_substeps"]
            h = dt / m
            usq = (ua[k] if th["rk4_sample"] == "current" else ua[k - 1]) ** 2

            def f(Tv, tv):
                tav = ta[k - 1] + (ta[k] - ta[k - 1]) * (tv / dt)
                a, b, g = _thermal_ab(Tv, tav, usq, th, name, var, p)
                return g * (-a * (Tv - tav) + b)

            for j in range(m):
                tv = j * h
                s1 = f(Tk, tv)
                s2 = f(Tk + 0.5 * h * s1, tv + 0.5 * h)
                s3 = f(Tk + 0.5 * h * s2, tv + 0.5 * h)
                s4 = f(Tk + h * s3, tv + h)
                Tk = Tk + h / 6.0 * (s1 + 2 * s2 + 2 * s3 + s4)
        T[k] = Tk
    x = np.array([_x_of_T(v, truth) for v in T])
    return {"T": T, "theta": T - ta0, "x_h": x, "u_applied": ua, "ambient": ta, "extra": extra}


def _initial_memory(hy: dict, x0: float) -> list[float]:
    kind = hy["memory"]["kind"]
    out = []
    for r, a, fr in zip(hy["r"], hy["alpha"], hy["memory"]["fractions"]):
        lo, up = x0 - r, a * (x0 + r)
        if kind == "zero":
            out.append(0.0)
        elif kind == "from_above":  # the input came down from x_max to x0
            top = max(hy["x_max"] - r, 0.0)
            out.append(max(lo, min(up, top)))
        else:  # random admissible state between the two bounding lines
            out.append(lo + fr * (max(lo, up) - lo))
    return out


def _soft_clip(h: float, hc: float, w: float) -> float:
    z = (hc - h) / w
    return hc - w * (z + math.log1p(math.exp(-z)) if z > 0 else math.log1p(math.exp(z)))


def _square(t: float, p: dict) -> float:
    ph = (t / p["period_s"] + p["phase"]) % 1.0
    e = p["edge_s"] / p["period_s"]
    return math.tanh(math.sin(2 * math.pi * ph) / max(e, 1e-3))


def _core(truth: dict, u: np.ndarray, dt: float, upto: str | None = None) -> dict:
    """Noise-free plant; returns the clean measured output and all internal signals."""
    u = np.asarray(u, dtype=float)
    if u.ndim != 1 or len(u) < 2 or not np.all(np.isfinite(u)):
        raise ValueError("u must be a finite 1-D array of at least 2 samples")
    out = _thermal_stage(truth, u, dt)
    if upto == "x":
        return out
    hy, se = truth["hysteresis"], truth["sensor"]
    eff = truth.get("effect") or {}
    name, var, p = eff.get("name"), eff.get("variant"), _effect_params(eff)
    x, theta = out["x_h"], out["theta"]
    n = len(x)
    trise = truth["thermal"]["trise_K"]
    rs, al, ws, G, poly = hy["r"], hy["alpha"], hy["w"], hy["G"], hy["poly"]
    F = _initial_memory(hy, float(x[0]))
    nops = len(rs)
    h = np.empty(n)
    y_clean = np.empty(n)
    # output-chain states
    xf_rate, x_prev = 0.0, float(x[0])
    creep = None
    strain = 0.0
    sens1 = sens2 = None
    ybuf: list[float] = []
    sign = 1.0 if se["orientation"] == "displacement" else -1.0
    off = se["offset_mm"]
    range_mm = hy["range_mm"]
    extra = out["extra"]
    a_f = 0.0
    if name == "rate_dependence":
        a_f = 1.0 - math.exp(-dt / p["tau_f_s"])
    for k in range(n):
        xk = float(x[k])
        tk = k * dt
        if name == "rate_dependence":
            rate = (xk - x_prev) / dt if k > 0 else 0.0
            xf_rate += a_f * (rate - xf_rate)
            x_prev = xk
        wfac = (
            1.0 + p["beta_s"] * abs(xf_rate) / hy["x_max"] if (name == "rate_dependence" and var == "threshold_widening") else 1.0
        )
        acc = G * xk + poly[0] * xk * xk + (poly[1] * xk**3 if len(poly) > 1 else 0.0)
        for i in range(nops):
            r = rs[i] * wfac
            lo, up = xk - r, al[i] * (xk + r)
            f = F[i]
            if f > up:
                f = up
            if f < lo:
                f = lo
            F[i] = f
            acc += ws[i] * f
        if name == "rate_dependence" and var == "viscous":
            acc += p["eta"] * xf_rate
        hk = acc
        if name == "output_saturation":
            if var == "tanh":
                hk = math.tanh(hk * p["inv_S_per_mm"]) / p["inv_S_per_mm"]
            else:
                hk = _soft_clip(hk, (1.0 - p["depth"]) * range_mm, p["knee_mm"])
        if name == "periodic_disturbance" and var == "square_load":
            hk = hk * (1.0 + p["m"] * _square(tk, p))
        h[k] = hk
        m = hk
        if name == "creep":
            if creep is None:
                creep = [kap * hk * p["initial_fraction"] for kap in p["kappa"]]
            for j, (kap, tau) in enumerate(zip(p["kappa"], p["tau_s"])):
                e = math.exp(-dt / tau)
                creep[j] = e * creep[j] + (1 - e) * kap * hk
            m += sum(creep)
        if name == "strain_accumulation":
            th_n = float(theta[k]) / trise / p["theta_ref"]
            if var == "threshold_linear":
                strain += dt * p["gamma_mm_per_s"] * max(0.0, th_n - p["th_fraction"])
            else:
                strain += dt * p["gamma_mm_per_s"] * math.exp(p["E"] * (th_n - 1.0)) * max(0.0, 1.0 - strain / p["s_max_mm"])
            m += strain
        if name == "extra_column" and var == "humidity":
            col = extra[p["column"]]
            m += p["coef_mm_per_pct"] * (col[k] - col[0])
        if name == "periodic_disturbance" and var == "sinusoid":
            m += p["A_mm"] * math.sin(2 * math.pi * p["f_hz"] * tk + p["phase"])
        yk = off + sign * m
        if name == "sensor_lag":
            e = math.exp(-dt / p["tau_s"])
            if sens1 is None:
                sens1 = sens2 = yk
            sens1 = e * sens1 + (1 - e) * yk
            if var == "second_order":
                sens2 = e * sens2 + (1 - e) * sens1
                yk = sens2
            else:
                yk = sens1
        if name == "delay" and var == "fractional":
            ybuf.append(yk)
            d = p["delay_s"] / dt
            d = math.floor(d) + p["fraction"]
            i0 = int(math.floor(d))
            fr = d - i0
            ya = ybuf[max(k - i0, 0)]
            yb = ybuf[max(k - i0 - 1, 0)]
            yk = (1 - fr) * ya + fr * yb
        if name == "gain_drift":
            g = 1.0 + (p["g_per_h"] * tk / 3600.0 if var == "linear" else p["g"] * (1.0 - math.exp(-tk / p["tau_s"])))
            yk = off + g * (yk - off)
        y_clean[k] = yk
    out.update({"h": h, "y_clean": y_clean})
    return out


def _choose_sensor(truth: dict, y_clean: np.ndarray) -> None:
    """Smallest standard full scale holding the clean output, placed at a random position; 16-bit LSB."""
    lo, hi = float(np.min(y_clean)), float(np.max(y_clean))
    span = max(hi - lo, 1e-6) * 1.3 + 1.0
    fs = next((v for v in _SENSOR_FULL_SCALES if v >= span), span)
    slack = fs - (hi - lo)
    start = lo - slack * truth["sensor"]["position"]
    truth["sensor"].update({"range_lo_mm": start, "range_hi_mm": start + fs, "lsb_mm": fs / (2 ** truth["sensor"]["bits"] - 1)})


def _finish(truth: dict, core: dict) -> dict:
    se, nz = truth["sensor"], truth["noise"]
    if "lsb_mm" not in se:
        raise ValueError("truth has no sensor range: build records with make_record (or call _choose_sensor)")
    yc = core["y_clean"]
    e = np.random.default_rng(nz["seed"]).normal(0.0, nz["sd"], len(yc))
    lo, lsb = se["range_lo_mm"], se["lsb_mm"]
    y = np.empty(len(yc))
    for k in range(len(yc)):  # sensor: add noise, then 16-bit conversion with clipping to the range
        q = round((yc[k] + e[k] - lo) / lsb)
        y[k] = lo + min(max(q, 0), 2 ** se["bits"] - 1) * lsb
    core = dict(core)
    core["y"] = y
    return core


def simulate(truth: dict, u, dt: float) -> dict:
    """Run the plant one sample at a time: dict(y, y_clean, theta, x_h, T, h, u_applied, ambient, extra)."""
    return _finish(truth, _core(truth, np.asarray(u, dtype=float), float(dt)))


# ----------------------------------------------------------------------------------------------
# Records
# ----------------------------------------------------------------------------------------------
def _ranges_ok(x: np.ndarray, h0: int, tol: float) -> bool:
    lo, hi = float(np.min(x[:h0])), float(np.max(x[:h0]))
    return float(np.min(x[h0:])) >= lo - tol and float(np.max(x[h0:])) <= hi + tol


def _excursion(truth: dict, u: np.ndarray, dt: float, h0: int, rng: np.random.Generator) -> tuple[np.ndarray, dict]:
    """Put one stretch above the trained voltage range (and thermal range) into the held-out part."""
    n = len(u)
    x_tr = _core(truth, u, dt, upto="x")["x_h"]
    u_hi, x_hi = float(np.max(u[:h0])), float(np.max(x_tr[:h0]))
    amount = rng.uniform(0.5, 1.5)  # volts above the trained maximum
    # voltage whose steady state reaches the trained maximum of the hysteresis input
    lo, hi = 0.0, 5.0 * truth["drive"]["u_max"]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if _x_of_T(_steady_T(truth, mid * mid), truth) < x_hi:
            lo = mid
        else:
            hi = mid
    level = max(u_hi, hi) + amount
    n_ho = n - h0
    k1 = truth["thermal"]["k1"]
    dur = int(round(min(max(rng.uniform(3.0, 5.0) / k1, 0.15 * n_ho * dt), 0.4 * n_ho * dt) / dt))
    dur = max(dur, 2)
    s0 = h0 + int(round(rng.uniform(0.1, 0.35) * n_ho))
    s1 = min(s0 + dur, n - 2)
    u = u.copy()
    u[s0:s1] = level
    x = _core(truth, u, dt, upto="x")["x_h"]
    tol = 1e-3 * max(x_hi, 1e-9)
    above = np.nonzero(x[h0:] > x_hi + tol)[0]
    x_start = int(h0 + above[0]) if len(above) else None
    x_end = int(h0 + above[-1] + 1) if len(above) else None
    span = {"amount_V": amount, "level_V": level, "trained_u_max_V": u_hi, "trained_x_max": x_hi,
            "start": s0, "end": s1, "start_s": s0 * dt, "end_s": s1 * dt,
            "state_start": x_start, "state_end": x_end,
            "state_start_s": None if x_start is None else x_start * dt, "state_end_s": None if x_end is None else x_end * dt}  # fmt: skip
    return u, span


def make_record(seed: int, *, effect: str | None = None, variant: str | None = None, drive: str | None = None,
                rate_hz: float | None = None, minutes: float | None = None, start: str | None = None,
                orientation: str | None = None, noise=None, excursion: bool = False, **truth_overrides) -> dict:  # fmt: skip
    """One randomised record: dict(time, u, y, y_clean, dt, noise_sd, truth, meta, heldout_start, excursion_span)."""
    r_opt = np.random.default_rng([int(seed), 0])
    family = drive or str(r_opt.choice(FAMILIES))
    rate = float(rate_hz) if rate_hz is not None else _logu(r_opt, 5.0, 100.0)
    mins = float(minutes) if minutes is not None else r_opt.uniform(5.0, 60.0)
    if family not in FAMILIES:
        raise ValueError(f"unknown drive family {family!r}; choose one of {FAMILIES}")
    dt = 1.0 / rate
    truth = random_truth(np.random.default_rng([int(seed), 1]), effect=effect, variant=variant, start=start,
                         orientation=orientation, noise=noise, **truth_overrides)  # fmt: skip
    clean_truth = copy.deepcopy(truth)
    clean_truth["effect"] = None
    n = int(round(mins * 60.0 / dt))
    h0 = int(round((1.0 - HELDOUT_FRACTION) * n))
    u_max = truth["drive"]["u_max"]
    meta = {"seed": int(seed), "drive": family, "rate_hz": rate, "minutes": mins, "n": n, "heldout_fraction": HELDOUT_FRACTION}
    # Drive whose held-out part stays inside the trained range (voltage: clipped; thermal state: redrawn, then shrunk).
    attempts, shrink = 0, 0
    for attempts in range(1, 21):
        u = make_drive(family, mins * 60.0, dt, np.random.default_rng([int(seed), 2, attempts]), u_max)
        u[h0:] = np.clip(u[h0:], float(np.min(u[:h0])), float(np.max(u[:h0])))
        x = _core(clean_truth, u, dt, upto="x")["x_h"]
        tol = 0.01 * float(np.ptp(x[:h0]))
        if _ranges_ok(x, h0, tol):
            break
    else:
        c = float(np.median(u[:h0]))
        while not _ranges_ok(x, h0, tol) and shrink < 40:
            shrink += 1
            u[h0:] = c + 0.85 * (u[h0:] - c)
            x = _core(clean_truth, u, dt, upto="x")["x_h"]
    meta.update(
        {"drive_attempts": attempts, "heldout_shrink_steps": shrink, "heldout_state_in_range": bool(_ranges_ok(x, h0, tol))}
    )
    meta["trained_u_range_V"] = [float(np.min(u[:h0])), float(np.max(u[:h0]))]
    meta["trained_x_range"] = [float(np.min(x[:h0])), float(np.max(x[:h0]))]
    span = None
    if excursion:
        u, span = _excursion(clean_truth, u, dt, h0, np.random.default_rng([int(seed), 4]))
    # Effect strength: measured against the clean plant and raised until it moves the output >= 5x the noise.
    base = _core(clean_truth, u, dt)
    sd = truth["noise"]["sd"]
    core = base
    if truth["effect"]:
        eff = truth["effect"]
        if "theta_ref" in eff["params"]:
            eff["params"]["theta_ref"] = max(float(np.max(base["theta"][:h0])) / truth["thermal"]["trise_K"], 1e-3)
        target = 5.5 * sd
        delta = 0.0
        for _ in range(8):
            core = _core(truth, u, dt)
            delta = float(np.std(core["y_clean"] - base["y_clean"]))  # de-meaned: a pure offset is no effect
            if delta >= target or eff["strength"] >= eff["max_strength"] * (1 - 1e-9):
                break
            grow = min(max(1.1 * target / max(delta, 1e-12), 1.3), 20.0)
            eff["strength"] = min(eff["strength"] * grow, eff["max_strength"])
        meta["effect_delta_std_mm"] = delta
        if delta <= 1e-9 * max(sd, 1e-12):
            raise RuntimeError(f"seed {seed}: effect {eff['name']}/{eff['variant']} does not change the output of this record")
        if delta < EFFECT_MIN_SNR * sd:  # strength capped at its physical limit: lower the noise instead
            truth["noise"]["sd"] = delta / 5.5
            truth["noise"]["reduced_for_effect"] = True
        meta["effect_delta_over_noise"] = delta / truth["noise"]["sd"]
        meta["effect_strength"] = eff["strength"]
    _choose_sensor(truth, core["y_clean"])
    sim = _finish(truth, core)
    if excursion:
        meta["heldout_state_in_range"] = None  # the excursion leaves it by design
    elif truth["effect"]:
        meta["heldout_state_in_range_with_effect"] = bool(_ranges_ok(sim["x_h"], h0, tol))
    time = np.arange(n) * dt
    return {"time": time, "u": u, "y": sim["y"], "y_clean": sim["y_clean"], "dt": dt, "noise_sd": truth["noise"]["sd"],
            "truth": truth, "meta": _py(meta), "heldout_start": h0, "excursion_span": _py(span),
            "extra": sim["extra"], "sim": sim}  # fmt: skip


def _atomic_write_text(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def truth_path(csv_path) -> Path:
    """NAME.csv -> NAME.truth.json (never NAME.json, which the toolkit reads as a sidecar)."""
    p = Path(csv_path)
    return p.with_name(p.stem + ".truth.json")


def write_csv(path, rec: dict) -> Path:
    """Write the record as CSV (time_s, voltage_V, displacement_mm, extra columns) and its truth JSON."""
    path = Path(path)
    cols = {"time_s": rec["time"], "voltage_V": rec["u"], "displacement_mm": rec["y"], **rec.get("extra", {})}
    names = list(cols)
    fmt = {"time_s": "{:.6f}", "voltage_V": "{:.6f}", "displacement_mm": "{:.7f}"}
    arrs = [np.asarray(cols[c], dtype=float) for c in names]
    lines = [",".join(names)]
    for row in zip(*arrs):
        lines.append(",".join(fmt.get(c, "{:.6g}").format(v) for c, v in zip(names, row)))
    _atomic_write_text(path, "\n".join(lines) + "\n")
    doc = {"csv": path.name, "dt": rec["dt"], "noise_sd": rec["noise_sd"], "heldout_start": rec["heldout_start"],
           "excursion_span": rec["excursion_span"], "meta": rec["meta"], "truth": rec["truth"]}  # fmt: skip
    _atomic_write_text(truth_path(path), json.dumps(_py(doc), indent=1))
    return path
