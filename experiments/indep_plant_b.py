"""A second independent SMA-fishing-line plant (plain numpy; shares no code with smafl_jax or tests/).

Why: the toolkit is judged on records from simulators it has never seen.  tests/indep_plant.py is a
play-operator cascade; this plant is the same physics with structurally different parts:

- thermal: lumped wire temperature T (degC), C dT/dt = V^2 / R(T) - h (T - Ta) - eps ((T+273)^4 - (Ta+273)^4),
  R(T) = R0 (1 + a (T - T0)), RK4 sub-steps inside each sample, the voltage a zero-order hold;
- phase fraction of the contracted (hot) phase, one of two classes drawn per seed:
  'preisach': relays with a continuous bivariate Gaussian density of (alpha, beta) switching temperatures on a
  fine triangle grid; 'ikuta': tanh major branches with an Ikuta / Likhachev-type reversal rule (after a
  reversal the branch is rescaled to run from the current fraction to the opposite major branch's limit);
- output = stroke * fraction + a small reversible term linear in T; sensor 'displacement' (rises on
  contraction) or 'length' (falls, plus an offset), optional first-order sensor lag, Gaussian noise, 1 um
  quantisation.

Within one sample the voltage is constant, so T (a 1-D autonomous ODE) is monotone there and a
rate-independent hysteresis updated at the sample's end temperature is exact.

    python experiments/indep_plant_b.py      # prints a few record summaries and writes /tmp/plant_b_loops.png
"""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

import numpy as np

DRIVES = ("pwm", "multisine", "steps", "staircase", "triangle")
RATES_HZ = (5, 10, 25, 50, 100)
STARTS = ("cold", "warm", "mid")
SENSORS = ("displacement", "length")
HYSTERESIS = ("preisach", "ikuta")
K0 = 273.15
SIGMA_SB = 5.670e-8
QUANTUM_MM = 0.001


# ----------------------------------------------------------------------------------------------- thermal
class Thermal:
    """Lumped Joule-heated wire; `advance(T, V, dt)` integrates one zero-order-hold sample with RK4."""

    def __init__(self, rng: np.random.Generator, t_target: float, ta: float):
        self.ta = ta
        self.r0 = float(rng.uniform(15.0, 40.0))  # ohm at t0
        self.t0 = 20.0
        self.a = float(rng.uniform(-5e-4, 1.5e-3))  # 1/K
        self.h = float(rng.uniform(0.004, 0.015))  # W/K convection
        radiative = bool(rng.random() < 0.5)
        area = math.pi * 1.5e-3 * 0.1
        self.eps = SIGMA_SB * float(rng.uniform(0.3, 0.9)) * area if radiative else 0.0
        tau = float(np.exp(rng.uniform(np.log(5.0), np.log(60.0))))
        tmid = 0.5 * (self.ta + t_target) + K0
        self.g_lin = self.h + 4.0 * self.eps * tmid**3
        self.c = tau * self.g_lin  # J/K
        self.tau = tau
        # drive that holds the wire at t_target in steady state
        p = self.loss(t_target)
        self.u_max = math.sqrt(p * self.resistance(t_target))
        self.t_max = t_target

    def resistance(self, t: float) -> float:
        return self.r0 * (1.0 + self.a * (t - self.t0))

    def loss(self, t: float) -> float:
        return self.h * (t - self.ta) + self.eps * ((t + K0) ** 4 - (self.ta + K0) ** 4)

    def rate(self, t: float, v: float) -> float:
        return (v * v / self.resistance(t) - self.loss(t)) / self.c

    def advance(self, t: float, v: float, dt: float, n_sub: int) -> float:
        h = dt / n_sub
        for _ in range(n_sub):
            k1 = self.rate(t, v)
            k2 = self.rate(t + 0.5 * h * k1, v)
            k3 = self.rate(t + 0.5 * h * k2, v)
            k4 = self.rate(t + h * k3, v)
            t = t + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        return t

    def steady(self, v: float) -> float:
        """Equilibrium temperature under a constant voltage (bisection on the heat balance)."""
        lo, hi = self.ta, self.ta + 400.0
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            if self.rate(mid, v) > 0:
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi)

    def truth(self) -> dict:
        return {
            "ta": self.ta,
            "r0": self.r0,
            "a": self.a,
            "h": self.h,
            "eps": self.eps,
            "c": self.c,
            "tau_s": self.tau,
            "k1": 1.0 / self.tau,
            "u_max": self.u_max,
            "t_max": self.t_max,
        }


# -------------------------------------------------------------------------------------------- hysteresis
class PreisachGauss:
    """Relays switching up at alpha and down at beta (alpha >= beta) weighted by a bivariate Gaussian density."""

    name = "preisach"

    def __init__(self, rng: np.random.Generator, ta: float, n: int = 150):
        self.a_mean = float(rng.uniform(55.0, 80.0))
        self.width = float(rng.uniform(10.0, 25.0))  # mean alpha - beta
        self.b_mean = self.a_mean - self.width
        self.sd_a = float(rng.uniform(3.5, 9.0))
        self.sd_b = float(rng.uniform(3.5, 9.0))
        self.rho = float(rng.uniform(0.2, 0.8))
        lo = max(ta + 2.0, self.b_mean - 4.0 * self.sd_b)
        hi = self.a_mean + 4.0 * self.sd_a
        g = np.linspace(lo, hi, n)
        aa, bb = np.meshgrid(g, g, indexing="ij")
        # each relay sits at a random point of its grid cell, so the switching temperatures are spread
        # continuously (a plain grid makes visible output steps at every grid temperature)
        cell = g[1] - g[0]
        aa = aa + rng.uniform(-0.5, 0.5, aa.shape) * cell
        bb = bb + rng.uniform(-0.5, 0.5, bb.shape) * cell
        keep = aa >= bb
        za = (aa - self.a_mean) / self.sd_a
        zb = (bb - self.b_mean) / self.sd_b
        dens = np.exp(-(za**2 - 2.0 * self.rho * za * zb + zb**2) / (2.0 * (1.0 - self.rho**2)))
        self.alpha = aa[keep]
        self.beta = bb[keep]
        w = dens[keep]
        self.w = w / w.sum()
        self.state = np.zeros(self.w.size, dtype=bool)
        self.n = n

    def update(self, t: float) -> float:
        self.state[self.alpha <= t] = True
        self.state[self.beta >= t] = False
        return float(self.w[self.state].sum())

    def heating_branch(self, t: float) -> float:
        return float(self.w[self.alpha <= t].sum())

    def t_for_heating_fraction(self, q: float) -> float:
        order = np.argsort(self.alpha)
        c = np.cumsum(self.w[order])
        return float(self.alpha[order][np.searchsorted(c, q)])

    def reset_cold(self, t: float) -> None:
        self.state[:] = False
        self.update(t)

    def truth(self) -> dict:
        return {
            "class": self.name,
            "alpha_mean": self.a_mean,
            "beta_mean": self.b_mean,
            "sd_alpha": self.sd_a,
            "sd_beta": self.sd_b,
            "rho": self.rho,
            "grid": self.n,
        }


class IkutaTanh:
    """tanh major branches; after a reversal at (T_r, x_r) the branch is rescaled towards the opposite limit (Ikuta)."""

    name = "ikuta"

    def __init__(self, rng: np.random.Generator, ta: float):
        self.th = float(rng.uniform(55.0, 80.0))
        self.wh = float(rng.uniform(3.0, 8.0))
        self.tc = self.th - float(rng.uniform(10.0, 25.0))
        self.wc = float(rng.uniform(3.0, 8.0))
        self.reset_cold(ta)

    def xh(self, t: float) -> float:
        return 0.5 * (1.0 + math.tanh((t - self.th) / self.wh))

    def xc(self, t: float) -> float:
        return 0.5 * (1.0 + math.tanh((t - self.tc) / self.wc))

    def _value(self, t: float) -> float:
        tr, xr = self.t_rev, self.x_rev
        if self.heating:
            den = 1.0 - self.xh(tr)
            return xr if den < 1e-300 else 1.0 - (1.0 - xr) * (1.0 - self.xh(t)) / den
        den = self.xc(tr)
        return xr if den < 1e-300 else xr * self.xc(t) / den

    def update(self, t: float) -> float:
        if t != self.t_last:
            heating = t > self.t_last
            if heating != self.heating:  # reversal: the new branch starts at the current point
                self.t_rev, self.x_rev, self.heating = self.t_last, self.x, heating
            self.x = min(1.0, max(0.0, self._value(t)))
            self.t_last = t
        return self.x

    def heating_branch(self, t: float) -> float:
        return self.xh(t)

    def t_for_heating_fraction(self, q: float) -> float:
        return self.th + self.wh * math.atanh(2.0 * q - 1.0)

    def reset_cold(self, t: float) -> None:
        # at rest on the cooling major branch, last move downwards
        self.heating = False
        self.t_rev, self.x_rev = t + 200.0, 1.0
        self.x = self.xc(t) / self.xc(self.t_rev)
        self.t_last = t

    def truth(self) -> dict:
        return {"class": self.name, "th": self.th, "wh": self.wh, "tc": self.tc, "wc": self.wc}


# ------------------------------------------------------------------------------------------------ drives
def _slow_curve(rng: np.random.Generator, t: np.ndarray, lo: float, hi: float, n_knots: int) -> np.ndarray:
    """A smooth random curve between lo and hi (cubic-ish interpolation of random knots)."""
    knots_t = np.linspace(t[0], t[-1], n_knots)
    knots_v = rng.uniform(lo, hi, n_knots)
    from scipy.interpolate import PchipInterpolator

    return np.clip(PchipInterpolator(knots_t, knots_v)(t), lo, hi)


def make_drive(rng: np.random.Generator, kind: str, t: np.ndarray, u_max: float, tau: float = 20.0) -> np.ndarray:
    """Voltage samples (held constant over each sample interval) of one drive family; tau sets slow sweeps."""
    n = t.size
    dur = float(t[-1] - t[0]) if n > 1 else 1.0
    if kind == "pwm":
        period = float(rng.uniform(2.0, 30.0))
        high = float(rng.uniform(0.85, 1.0)) * u_max
        duty = _slow_curve(rng, t, 0.05, 0.95, max(4, int(dur / 90.0)))
        phase = np.mod(t / period, 1.0)
        return np.where(phase < duty, high, 0.0)
    if kind == "multisine":
        m = int(rng.integers(3, 7))
        freqs = np.exp(rng.uniform(np.log(0.005), np.log(0.2), m))
        amps = rng.uniform(0.3, 1.0, m) / np.sqrt(np.arange(1, m + 1))
        ph = rng.uniform(0.0, 2.0 * np.pi, m)
        s = (amps[None, :] * np.sin(2.0 * np.pi * freqs[None, :] * t[:, None] + ph[None, :])).sum(1)
        s = 2.0 * (s - s.min()) / max(np.ptp(s), 1e-12) - 1.0  # -1..1
        centre = float(rng.uniform(0.7, 0.85))
        swing = float(rng.uniform(0.25, 0.4))
        return np.clip(centre + swing * s, 0.0, 1.0) * u_max
    if kind == "steps":
        u = np.empty(n)
        i = 0
        while i < n:
            hold = float(rng.uniform(10.0, 120.0))
            j = int(np.searchsorted(t, t[i] + hold))
            # uniform in heat, and about a third of the steps near full drive so the wire transforms
            lev = math.sqrt(rng.uniform(0.0, 1.0)) if rng.random() < 0.65 else rng.uniform(0.85, 1.0)
            u[i : max(j, i + 1)] = lev * u_max
            i = max(j, i + 1)
        return u
    if kind == "staircase":
        u = np.empty(n)
        i = 0
        while i < n:
            peak = math.sqrt(rng.uniform(0.7, 1.0))
            n_lev = int(rng.integers(3, 7))
            levels = np.concatenate([np.linspace(0.0, peak, n_lev + 1)[1:], np.linspace(peak, 0.0, n_lev + 1)[1:]])
            for lev in levels:
                hold = float(rng.uniform(10.0, 60.0))
                j = int(np.searchsorted(t, t[i] + hold)) if i < n else n
                u[i : max(j, i + 1)] = lev * u_max
                i = max(j, i + 1)
                if i >= n:
                    break
        return u
    if kind == "triangle":
        u = np.empty(n)
        i = 0
        while i < n:
            period = float(rng.uniform(max(60.0, 4.0 * tau), max(240.0, 8.0 * tau)))
            lo = float(rng.uniform(0.0, 0.4))
            hi = math.sqrt(rng.uniform(0.7, 1.0))
            j = int(np.searchsorted(t, t[i] + period))
            seg = t[i:j] - t[i]
            u[i:j] = (lo + (hi - lo) * (1.0 - np.abs(2.0 * seg / period - 1.0))) * u_max
            i = max(j, i + 1)
        return u
    raise ValueError(f"unknown drive {kind!r}; choose from {DRIVES}")


# ------------------------------------------------------------------------------------------------ record
def _simulate(th: Thermal, hy, volts: np.ndarray, dt: float, t_init: float, n_sub: int):
    temp = np.empty(volts.size)
    frac = np.empty(volts.size)
    t = t_init
    for k, v in enumerate(volts):
        # sample k is the state at time k*dt; the drive volts[k] then holds over [k dt, (k+1) dt)
        temp[k] = t
        frac[k] = hy.update(t)
        t = th.advance(t, float(v), dt, n_sub)
    return temp, frac, t


def make_record(
    seed: int,
    drive: str = "steps",
    rate_hz: float = 10.0,
    minutes: float = 10.0,
    start: str = "cold",
    sensor: str = "displacement",
    noise_sd: float = 0.005,
    hysteresis: str | None = None,
    linear_thermal: bool = False,
) -> dict:
    """One simulated record; the last 30 % (from `heldout_start`) is kept inside the first 70 %'s voltage range.

    ``linear_thermal`` (an ablation): the same draws, but no radiation and a constant resistance, so the heat
    balance is a linear first-order lag in V^2 with the same time constant.
    """
    if start not in STARTS or sensor not in SENSORS:
        raise ValueError(f"start must be one of {STARTS}, sensor one of {SENSORS}")
    rng = np.random.default_rng([seed, DRIVES.index(drive), int(rate_hz * 10), STARTS.index(start), SENSORS.index(sensor)])
    hy_name = hysteresis if hysteresis is not None else HYSTERESIS[int(rng.integers(0, 2))]
    ta = float(rng.uniform(18.0, 28.0))
    hy = PreisachGauss(rng, ta) if hy_name == "preisach" else IkutaTanh(rng, ta)
    q_top = float(rng.uniform(0.85, 0.995))  # heating-branch fraction reached at steady full drive
    t_target = hy.t_for_heating_fraction(q_top)
    th = Thermal(rng, t_target, ta)
    if linear_thermal:
        th.eps, th.a = 0.0, 0.0
        th.c = th.tau * th.h
        th.u_max = math.sqrt(th.loss(t_target) * th.resistance(t_target))
    dt = 1.0 / rate_hz
    n = int(round(minutes * 60.0 * rate_hz))
    time = np.arange(n) * dt
    n_sub = max(1, math.ceil(dt / (th.tau / 50.0)))
    volts = make_drive(rng, drive, time, th.u_max, th.tau)
    h0 = int(round(0.7 * n))
    lo, hi = volts[:h0].min(), volts[:h0].max()
    clipped = int(np.sum((volts[h0:] < lo) | (volts[h0:] > hi)))
    volts[h0:] = np.clip(volts[h0:], lo, hi)

    # initial state: the pre-history is simulated with the same plant so memory and temperature agree
    hy.reset_cold(th.ta)
    t_init = th.ta
    pre = {"kind": start}
    if start in ("warm", "mid"):
        v_pre = float(rng.uniform(0.4, 0.85)) * th.u_max
        pre["v_pre"] = v_pre
        dt_pre = 0.05
        n_sub_pre = max(1, math.ceil(dt_pre / (th.tau / 50.0)))
        if start == "warm":
            seq = np.full(int(10.0 * th.tau / dt_pre), v_pre)
        else:
            t_on = float(rng.uniform(0.5, 2.0)) * th.tau
            t_off = float(rng.uniform(0.2, 1.0)) * th.tau
            pre.update(t_on_s=t_on, t_off_s=t_off)
            seq = np.concatenate([np.full(int(t_on / dt_pre), v_pre), np.zeros(int(t_off / dt_pre))])
        _, _, t_init = _simulate(th, hy, seq, dt_pre, th.ta, n_sub_pre)

    temp, frac, _ = _simulate(th, hy, volts, dt, t_init, n_sub)

    stroke = float(rng.uniform(2.0, 8.0))  # mm
    expand = float(rng.uniform(0.03, 0.2)) * stroke / max(th.t_max - th.ta, 1.0)  # mm/K, reversible
    y = stroke * frac + expand * (temp - th.ta)
    lag = float(rng.uniform(0.02, 0.3)) if rng.random() < 0.3 else 0.0
    if lag > 0:
        a = math.exp(-dt / lag)
        ys = np.empty_like(y)
        ys[0] = y[0]
        for k in range(1, n):
            ys[k] = a * ys[k - 1] + (1.0 - a) * y[k - 1]
        y = ys
    offset = 0.0
    if sensor == "length":
        offset = float(rng.uniform(10.0, 50.0))
        y = offset - y
    noisy = np.round((y + rng.normal(0.0, noise_sd, n)) / QUANTUM_MM) * QUANTUM_MM
    t_tr = temp[:h0]
    inside = (temp[h0:] >= t_tr.min()) & (temp[h0:] <= t_tr.max())
    return {
        "time": time,
        "voltage": volts,
        "output": noisy,
        "output_clean": y,
        "noise_sd": noise_sd,
        "heldout_start": h0,
        "truth": {
            "seed": seed,
            "drive": drive,
            "rate_hz": rate_hz,
            "minutes": minutes,
            "start": pre,
            "sensor": sensor,
            "orientation": "rises" if sensor == "displacement" else "falls",
            "hysteresis": hy.truth(),
            "thermal": th.truth(),
            "n_sub": n_sub,
            "heating_fraction_at_u_max": q_top,
            "stroke_mm": stroke,
            "expansion_mm_per_K": expand,
            "sensor_lag_s": lag,
            "length_offset_mm": offset,
            "quantum_mm": QUANTUM_MM,
            "t_init": float(t_init),
            "heldout_clipped_samples": clipped,
            "heldout_T_inside_fraction": float(inside.mean()),
            "heldout_T_inside": bool(inside.all()),
            "temperature": temp,
            "fraction": frac,
        },
    }


def write_csv(path: str | os.PathLike, rec: dict, stop: int | None = None) -> Path:
    """time_s, voltage_V, displacement_mm (that name even for a length sensor, as users do); atomic."""
    path = Path(path)
    sl = slice(0, stop)
    data = np.column_stack([rec["time"][sl], rec["voltage"][sl], rec["output"][sl]])
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


def _summary(rec: dict) -> str:
    tr = rec["truth"]
    temp = tr["temperature"]
    return (
        f"seed {tr['seed']} {tr['drive']:9s} {tr['rate_hz']:>5} Hz {tr['start']['kind']:4s} {tr['sensor']:12s} "
        f"{tr['hysteresis']['class']:8s} tau {tr['thermal']['tau_s']:5.1f} s  U_max {tr['thermal']['u_max']:4.2f} V  "
        f"T {temp.min():5.1f}..{temp.max():5.1f} C  frac {tr['fraction'].min():.2f}..{tr['fraction'].max():.2f}  "
        f"y {rec['output'].min():6.2f}..{rec['output'].max():6.2f} mm  held-out T inside {tr['heldout_T_inside_fraction']:.2f}  "
        f"lag {tr['sensor_lag_s']:.2f} s"
    )


if __name__ == "__main__":
    import time as _time

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    recs = []
    for i, (drive, start, sensor) in enumerate(
        [
            ("triangle", "cold", "displacement"),
            ("pwm", "warm", "length"),
            ("steps", "mid", "displacement"),
            ("multisine", "cold", "length"),
            ("staircase", "mid", "displacement"),
        ]
    ):
        for hyst in HYSTERESIS:
            t0 = _time.perf_counter()
            r = make_record(i + 1, drive=drive, rate_hz=RATES_HZ[i], minutes=10, start=start, sensor=sensor, hysteresis=hyst)
            print(_summary(r), f"({_time.perf_counter() - t0:.1f} s)")
            recs.append(r)
    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    for col, hyst in enumerate(HYSTERESIS):
        r = next(x for x in recs if x["truth"]["hysteresis"]["class"] == hyst and x["truth"]["drive"] == "triangle")
        tr = r["truth"]
        axes[0, col].plot(tr["temperature"], r["output_clean"], lw=0.6)
        axes[0, col].set(xlabel="T (C)", ylabel="output clean (mm)", title=f"{hyst}: triangle, T vs output")
        axes[1, col].plot(r["time"], r["output"], lw=0.5, label="output")
        ax2 = axes[1, col].twinx()
        ax2.plot(r["time"], r["voltage"], "r", lw=0.5)
        axes[1, col].axvline(r["time"][r["heldout_start"]], color="k", ls="--")
        axes[1, col].set(xlabel="t (s)", ylabel="mm")
    fig.tight_layout()
    fig.savefig("/tmp/plant_b_loops.png", dpi=90)
    print("wrote /tmp/plant_b_loops.png")
