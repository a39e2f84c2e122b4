"""Plant D: an independent simulator of a Joule-heated SMA wire with the thermal physics the toolkit's cascade lacks.

Plain numpy, one sample at a time (sub-stepped), no smafl_jax import; written in session 55 without reusing the
other generators' code (tests/indep_plant.py, experiments/indep_plant_b.py, experiments/indep_plant_c.py).  Why: the
toolkit's cascade is Joule heat -> ONE first-order lag -> hysteresis.  A real wire (and another lab's simulator) has
more: a second, slower thermal node (a sleeve, a coil former, the clamps), cooling that is not linear in the
temperature rise, a resistance that moves with temperature and phase, the latent heat of the transformation (the
temperature plateaus while the wire transforms), and a displacement sensor with its own lag.  Each is drawn per seed,
each can be switched off (``physics``) to find which one a fit cannot absorb.

Per sub-step (``h`` <= tau_w / 20), wire temperature ``Tw``, sleeve ``Ts``, austenite (contracted) fraction ``xi``:

    R     = R0 (1 + aR (Tw - Ta)) (1 - rho xi)                       resistance (NiTi: lower when austenitic)
    P     = U^2 / R
    Cw dTw/dt = P - Gws (Tw - Ts) - Gwa(Tw) (Tw - Ta) - L dxi/dt      Gwa = G0 (1 - c + c ((Tw - Ta) / 50)^0.25)
    Cs dTs/dt = Gws (Tw - Ts) - Gsa (Ts - Ta)
    xi    : Liang-Rogers cosine kinetics on Tw (As, Af on heating, Ms, Mf on cooling), a reversal branch rescaled from
            the point where it starts (the cosine of the branch is exactly 0 / 1 outside its window)
    y     = stroke * xi + expansion (Tw - Ta)                          mm; sensor: first-order lag, noise, quantised;
            a length sensor reads offset - y

Drives (drawn per record): PWM (period 0.5-20 s, slowly varying duty), multisine, steps, triangle sweeps.  Starts:
cold (ambient, martensite, power on at t = 0), warm (after a long hold at a random voltage) or mid (after a hold
then a cool-down of random length).  The last 30 % of the voltage is clipped into the first 70 %'s range.

    python experiments/indep_plant_d.py          # prints a few records' summaries
"""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

import numpy as np

DRIVES = ("pwm", "multisine", "steps", "triangle")
STARTS = ("cold", "warm", "mid")
SENSORS = ("displacement", "length")
#: every physical element this plant can switch off (``make_record(physics=...)``)
PHYSICS = ("sleeve", "convection", "resistance", "latent", "sensor_lag")
QUANTUM = 0.001  # mm


class Wire:
    """Thermal state (Tw, Ts) and the transformation (xi) of one wire; ``advance`` integrates one drive interval."""

    def __init__(self, rng: np.random.Generator, physics: set[str]):
        self.ta = float(rng.uniform(18.0, 28.0))
        # transformation temperatures (C): Mf < Ms < As < Af, as NiTi wires are sold (actuator grade 70-90 C Af)
        self.as_ = float(rng.uniform(45.0, 70.0))
        self.af = self.as_ + float(rng.uniform(8.0, 20.0))
        self.ms = self.as_ - float(rng.uniform(5.0, 20.0))
        self.mf = self.ms - float(rng.uniform(8.0, 20.0))
        self.tau_w = float(rng.uniform(0.5, 6.0))  # s, wire alone to its surroundings
        self.r0 = float(rng.uniform(5.0, 40.0))
        self.a_r = float(rng.uniform(-0.001, 0.003)) if "resistance" in physics else 0.0
        self.rho = float(rng.uniform(0.03, 0.15)) if "resistance" in physics else 0.0
        self.c_conv = float(rng.uniform(0.3, 0.8)) if "convection" in physics else 0.0
        # the wire's heat capacity sets the scale; conductances follow from the time constants
        self.cw = 1.0
        g_total = self.cw / self.tau_w
        if "sleeve" in physics:
            share = float(rng.uniform(0.2, 0.6))  # fraction of the wire's loss that goes through the sleeve
            self.gws = share * g_total
            self.g0 = (1.0 - share) * g_total
            self.tau_s = float(rng.uniform(20.0, 150.0))
            self.gsa = float(rng.uniform(0.3, 1.5)) * self.gws  # the sleeve's own loss relative to its coupling
            self.cs = self.tau_s * (self.gws + self.gsa)
        else:
            self.gws, self.g0, self.tau_s, self.gsa, self.cs = 0.0, g_total, 0.0, 0.0, 1.0
        self.latent = float(rng.uniform(3.0, 20.0)) * self.cw if "latent" in physics else 0.0  # K-equivalent x Cw
        self.stroke = float(rng.uniform(2.0, 8.0))  # mm
        self.expansion = float(rng.uniform(0.002, 0.02))  # mm/K
        # full drive reaches Af + margin at steady state (found by bisection on the steady balance)
        self.t_full = self.af + float(rng.uniform(5.0, 25.0))
        self.u_max = self._steady_voltage(self.t_full)
        self.reset()

    # -- thermal ---------------------------------------------------------------------------------------------------
    def _resistance(self, tw: float, xi: float) -> float:
        return self.r0 * (1.0 + self.a_r * (tw - self.ta)) * (1.0 - self.rho * xi)

    def _g_air(self, tw: float) -> float:
        rise = max(tw - self.ta, 0.0)
        return self.g0 * (1.0 - self.c_conv + self.c_conv * (rise / 50.0) ** 0.25)

    def _steady_loss(self, tw: float) -> float:
        """Heat flow out of the wire at a steady temperature ``tw`` (the sleeve at its own steady point)."""
        rise = tw - self.ta
        if self.gws > 0:
            g_series = self.gws * self.gsa / (self.gws + self.gsa)
        else:
            g_series = 0.0
        return (self._g_air(tw) + g_series) * rise

    def _steady_voltage(self, tw: float) -> float:
        return math.sqrt(self._steady_loss(tw) * self._resistance(tw, 1.0))

    # -- transformation (Liang-Rogers cosine kinetics, rescaled reversal branches) ---------------------------------
    def _heating_major(self, t: float) -> float:
        if t <= self.as_:
            return 0.0
        if t >= self.af:
            return 1.0
        return 0.5 * (1.0 - math.cos(math.pi * (t - self.as_) / (self.af - self.as_)))

    def _cooling_major(self, t: float) -> float:
        if t >= self.ms:
            return 1.0
        if t <= self.mf:
            return 0.0
        return 0.5 * (1.0 + math.cos(math.pi * (self.ms - t) / (self.ms - self.mf)))

    def _transform(self, t: float) -> float:
        if t > self.t_prev and not self.heating:
            self.heating, self.xi_rev, self.f_rev = True, self.xi, self._heating_major(self.t_prev)
        elif t < self.t_prev and self.heating:
            self.heating, self.xi_rev, self.f_rev = False, self.xi, self._cooling_major(self.t_prev)
        if self.heating:
            # the heating branch from the reversal point (xi_r) to 1, following the major branch's progress
            den = 1.0 - self.f_rev
            f = self._heating_major(t)
            xi = self.xi_rev if den < 1e-12 else 1.0 - (1.0 - self.xi_rev) * (1.0 - f) / den
            xi = max(xi, self.xi)  # heating never reverts austenite
        else:
            den = self.f_rev
            f = self._cooling_major(t)
            xi = self.xi_rev if den < 1e-12 else self.xi_rev * f / den
            xi = min(xi, self.xi)
        self.t_prev = t
        return min(1.0, max(0.0, xi))

    def reset(self) -> None:
        """Cold: ambient, fully martensitic, last move a cooling."""
        self.tw = self.ts = self.ta
        self.xi = 0.0
        self.heating = False
        self.xi_rev, self.f_rev = 0.0, self._cooling_major(self.ta)
        self.t_prev = self.ta

    def advance(self, u: float, dt: float) -> None:
        n_sub = max(1, math.ceil(dt / (self.tau_w / 20.0)))
        h = dt / n_sub
        for _ in range(n_sub):
            p = u * u / self._resistance(self.tw, self.xi)
            q_w = p - self.gws * (self.tw - self.ts) - self._g_air(self.tw) * (self.tw - self.ta)
            q_s = self.gws * (self.tw - self.ts) - self.gsa * (self.ts - self.ta)
            tw_new = self.tw + h * q_w / self.cw
            ts_new = self.ts + h * q_s / self.cs if self.gws > 0 else self.ta
            xi_new = self._transform(tw_new)
            # latent heat: the transformation absorbs heat on heating (M -> A) and releases it on cooling
            tw_new -= self.latent * (xi_new - self.xi) / self.cw
            self.tw, self.ts, self.xi = tw_new, ts_new, xi_new

    def truth(self) -> dict:
        return {
            "ta": self.ta, "As": self.as_, "Af": self.af, "Ms": self.ms, "Mf": self.mf, "tau_wire_s": self.tau_w,
            "tau_sleeve_s": self.tau_s, "sleeve_share": self.gws / (self.gws + self.g0), "r0": self.r0, "a_r": self.a_r,
            "rho": self.rho, "convection_c": self.c_conv, "latent_K": self.latent / self.cw, "u_max": self.u_max,
            "t_full": self.t_full, "stroke_mm": self.stroke, "expansion_mm_per_K": self.expansion,
        }  # fmt: skip


def _drive(rng: np.random.Generator, kind: str, t: np.ndarray, u_max: float) -> np.ndarray:
    n, dur = t.size, float(t[-1] - t[0])
    if kind == "pwm":
        period = float(np.exp(rng.uniform(np.log(0.5), np.log(20.0))))
        knots = rng.uniform(0.05, 0.95, max(4, int(dur / 60.0)))
        duty = np.interp(t, np.linspace(t[0], t[-1], knots.size), knots)
        return np.where(np.mod(t / period, 1.0) < duty, float(rng.uniform(0.9, 1.0)) * u_max, 0.0)
    if kind == "multisine":
        m = int(rng.integers(3, 6))
        f = np.exp(rng.uniform(np.log(0.004), np.log(0.15), m))
        s = np.sum(rng.uniform(0.3, 1.0, m) * np.sin(2 * np.pi * f * t[:, None] + rng.uniform(0, 2 * np.pi, m)), axis=1)
        s = (s - s.min()) / max(np.ptp(s), 1e-12)
        return np.sqrt(np.clip(float(rng.uniform(0.0, 0.2)) + float(rng.uniform(0.8, 1.0)) * s, 0.0, 1.0)) * u_max
    if kind == "steps":
        u, i = np.empty(n), 0
        while i < n:
            j = max(i + 1, int(np.searchsorted(t, t[i] + float(rng.uniform(5.0, 90.0)))))
            u[i:j] = math.sqrt(float(rng.uniform(0.0, 1.0))) * u_max
            i = j
        return u
    if kind == "triangle":
        u, i = np.empty(n), 0
        while i < n:
            period = float(rng.uniform(40.0, 300.0))
            lo, hi = float(rng.uniform(0.0, 0.3)), float(rng.uniform(0.75, 1.0))
            j = max(i + 1, int(np.searchsorted(t, t[i] + period)))
            ph = (t[i:j] - t[i]) / period
            u[i:j] = np.sqrt(lo + (hi - lo) * (1.0 - np.abs(2.0 * ph - 1.0))) * u_max
            i = j
        return u
    raise ValueError(f"unknown drive {kind!r}; choose from {DRIVES}")


def make_record(
    seed: int,
    drive: str = "pwm",
    rate_hz: float = 25.0,
    minutes: float = 10.0,
    start: str = "cold",
    sensor: str = "displacement",
    noise_sd: float = 0.005,
    physics: tuple[str, ...] = PHYSICS,
) -> dict:
    """One record: time, voltage, noisy and clean output, ``heldout_start`` (70 %), the drawn truth."""
    if drive not in DRIVES or start not in STARTS or sensor not in SENSORS:
        raise ValueError(f"drive in {DRIVES}, start in {STARTS}, sensor in {SENSORS}")
    unknown = set(physics) - set(PHYSICS)
    if unknown:
        raise ValueError(f"unknown physics {sorted(unknown)}; choose from {PHYSICS}")
    # the draw of the wire does not depend on the physics switched on, so ablations compare like with like
    rng = np.random.default_rng([seed, DRIVES.index(drive), int(round(rate_hz * 10)), STARTS.index(start)])
    wire = Wire(np.random.default_rng([seed, 7]), set(physics))
    dt = 1.0 / rate_hz
    n = int(round(minutes * 60.0 * rate_hz))
    t = np.arange(n) * dt
    volts = _drive(rng, drive, t, wire.u_max)
    h0 = int(round(0.7 * n))
    volts[h0:] = np.clip(volts[h0:], volts[:h0].min(), volts[:h0].max())
    pre = {"kind": start}
    if start != "cold":
        v_pre = float(rng.uniform(0.5, 0.95)) * wire.u_max
        hold = float(rng.uniform(60.0, 400.0))
        pre.update(v_pre=v_pre, hold_s=hold)
        for _ in range(int(hold / 0.05)):
            wire.advance(v_pre, 0.05)
        if start == "mid":
            off = float(rng.uniform(1.0, 20.0))
            pre["off_s"] = off
            for _ in range(int(off / 0.05)):
                wire.advance(0.0, 0.05)
    tw, xi = np.empty(n), np.empty(n)
    for k in range(n):  # sample k is the state at t_k; volts[k] then holds over [t_k, t_k + dt)
        tw[k], xi[k] = wire.tw, wire.xi
        wire.advance(float(volts[k]), dt)
    y = wire.stroke * xi + wire.expansion * (tw - wire.ta)
    lag = float(rng.uniform(0.05, 0.5)) if "sensor_lag" in physics and rng.random() < 0.5 else 0.0
    if lag > 0:
        a = math.exp(-dt / lag)
        ys = np.empty_like(y)
        ys[0] = y[0]
        for k in range(1, n):
            ys[k] = a * ys[k - 1] + (1.0 - a) * y[k]
        y = ys
    offset = float(rng.uniform(20.0, 60.0)) if sensor == "length" else 0.0
    if sensor == "length":
        y = offset - y
    noisy = np.round((y + rng.normal(0.0, noise_sd, n)) / QUANTUM) * QUANTUM
    return {
        "time": t,
        "voltage": volts,
        "output": noisy,
        "output_clean": y,
        "noise_sd": noise_sd,
        "heldout_start": h0,
        "truth": {
            "seed": seed, "drive": drive, "rate_hz": rate_hz, "minutes": minutes, "start": pre, "sensor": sensor,
            "physics": list(physics), "wire": wire.truth(), "sensor_lag_s": lag, "length_offset_mm": offset,
            "temperature": tw, "fraction": xi,
        },
    }  # fmt: skip


def write_csv(path: str | os.PathLike, rec: dict, stop: int | None = None) -> Path:
    """time_s, voltage_V, displacement_mm (rows up to ``stop``); written to a temporary file, then renamed."""
    path = Path(path)
    data = np.column_stack([rec["time"][:stop], rec["voltage"][:stop], rec["output"][:stop]])
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write("time_s,voltage_V,displacement_mm\n")
            np.savetxt(fh, data, delimiter=",", fmt=["%.6f", "%.6f", "%.4f"])
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    return path


if __name__ == "__main__":
    for s, (d, st, se) in enumerate(
        [("pwm", "cold", "displacement"), ("multisine", "warm", "length"), ("steps", "mid", "displacement")]
    ):
        r = make_record(s, drive=d, start=st, sensor=se)
        w, tw, xi = r["truth"]["wire"], r["truth"]["temperature"], r["truth"]["fraction"]
        print(
            f"seed {s} {d:9s} {st:4s} {se:12s} tau_w {w['tau_wire_s']:.1f} s sleeve {w['tau_sleeve_s']:.0f} s "
            f"({w['sleeve_share']:.2f}) latent {w['latent_K']:.1f} K  Tw {tw.min():.1f}..{tw.max():.1f} C "
            f"(As {w['As']:.0f} Af {w['Af']:.0f} Ms {w['Ms']:.0f} Mf {w['Mf']:.0f})  xi {xi.min():.2f}..{xi.max():.2f}  "
            f"U_max {w['u_max']:.2f} V"
        )
