"""Plant C: an independent, from-scratch simulator of a Joule-heated hysteretic muscle.

Plain numpy, one sample at a time, no smafl_jax import. Written in session 43 (new-user trial 7) by a helper that did
not read the repository's other generators (tests/indep_plant.py, experiments/indep_plant_b.py), so it shares neither
code nor conventions with them.  Runner: experiments/plant_c_trial.py.

Cascade (per sample k, sample time dt, drive U[k] held over (t_{k-1}, t_k]):
    heat       P = U^2 / R
    thermal    dT/dt = -k1 (T - T_amb) + k2 P       (exact ZOH discretisation)
    hyst. in.  x = sqrt(max(T - T_amb, 0) k1 R / k2)  ('veff', volts at steady state)
               or x = T - T_amb                       ('temp', kelvin)
    play ops   F_i[k] = max(x - r_i, min(a_i (x + r_i), F_i[k-1]))   (a_i = 1: classical)
    output     y = sum_i w_i F_i + c2 x^2 + c3 x^3 + y0         (mm, rises on contraction)
    sensor     displacement: y + noise, quantised;  length: offset - y + noise, quantised

Cold start: T = T_amb at t=0, drive already on (U[0] > 0 possible); operators at their value after a long
history that ended at ambient input (heated earlier, then cooled: each op on its upper bound a_i * r_i at x=0).
Warm start: a random 3-6 min pre-history drive is run from the cold state first, its final T and operator
states are the record's start (the pre-history is not recorded).
"""

from __future__ import annotations

import json
import math
import os
import sys

import numpy as np

T_AMB = 22.0


def draw_plant(seed: int, sees: str | None = None) -> dict:
    rng = np.random.default_rng(seed)
    tau = float(rng.uniform(5.0, 40.0))
    k1 = 1.0 / tau
    R = float(rng.uniform(20.0, 60.0))
    dT7 = float(rng.uniform(40.0, 90.0))  # steady temperature rise at 7 V
    k2 = dT7 * k1 * R / 49.0
    sees = sees or ("veff" if rng.uniform() < 0.6 else "temp")
    xmax = 7.0 if sees == "veff" else dT7  # nominal input span of the hysteresis
    n = int(rng.integers(3, 8))
    r = np.sort(rng.uniform(0.02, 0.30, n))
    r[0] = rng.uniform(0.01, 0.05)
    r = np.sort(r) * xmax
    a = np.ones(n)
    n_tilt = int(rng.integers(1, n))  # at least one tilted, at least one classical
    idx = rng.choice(n, n_tilt, replace=False)
    a[idx] = rng.uniform(0.5, 3.0, n_tilt)
    w = rng.uniform(0.2, 1.0, n)
    # scale the gains to a target stroke
    stroke = float(rng.uniform(2.5, 8.0))
    c2 = float(rng.uniform(-0.08, 0.08))
    c3 = float(rng.uniform(-0.04, 0.04))
    plant = dict(
        seed=seed,
        tau=tau,
        k1=k1,
        k2=k2,
        R=R,
        T_amb=T_AMB,
        dT_at_7V=dT7,
        sees=sees,
        xmax=xmax,
        r=r.tolist(),
        alpha=a.tolist(),
        w=w.tolist(),
        c2_rel=c2,
        c3_rel=c3,
        y0=0.0,
    )
    # stroke normalisation: quasi-static rise 0 -> xmax from the descended state
    x = np.linspace(0, xmax, 400)
    y = _static_path(plant, x, w)
    s = stroke / (y[-1] - y[0])
    plant["w"] = (w * s).tolist()
    plant["c2"] = c2 * stroke / xmax**2
    plant["c3"] = c3 * stroke / xmax**3
    plant["stroke_mm"] = stroke
    # zero the sensor at cold rest: output 0 at ambient after the long history
    plant["y0"] = -float(np.dot(plant["w"], np.array(plant["alpha"]) * np.array(plant["r"])))
    return plant


def _static_path(p, xs, w):
    r = np.array(p["r"])
    a = np.array(p["alpha"])
    F = a * r
    out = []
    for x in xs:
        F = np.maximum(x - r, np.minimum(a * (x + r), F))
        out.append(float(np.dot(w, F)))  # gains only
    return np.array(out)


def simulate(p: dict, U: np.ndarray, dt: float, T0: float | None = None, F0=None):
    """Noise-free: returns (y, T, x, F_end). One sample at a time."""
    r = np.array(p["r"])
    a = np.array(p["alpha"])
    w = np.array(p["w"])
    k1, k2, R, Ta = p["k1"], p["k2"], p["R"], p["T_amb"]
    e = math.exp(-k1 * dt)
    T = Ta if T0 is None else T0
    F = a * r if F0 is None else np.array(F0, float)
    ys = np.empty(len(U))
    Ts = np.empty(len(U))
    xs = np.empty(len(U))
    for k, u in enumerate(U):
        if k > 0:  # sample k's drive held over (t_{k-1}, t_k]; T[0] is the start state
            T = Ta + (T - Ta) * e + (k2 / k1) * (u * u / R) * (1.0 - e)
        dTh = max(T - Ta, 0.0)
        x = math.sqrt(dTh * k1 * R / k2) if p["sees"] == "veff" else dTh
        for i in range(len(r)):
            lo = x - r[i]
            hi = a[i] * (x + r[i])
            f = F[i]
            if f > hi:
                f = hi
            if f < lo:
                f = lo
            F[i] = f
        y = float(np.dot(w, F)) + p["c2"] * x * x + p["c3"] * x**3 + p["y0"]
        ys[k] = y
        Ts[k] = T
        xs[k] = x
    return ys, Ts, xs, F.copy()


# ---------------------------------------------------------------- drives
def drive_pwm(rng, t, amp=None):
    period = float(rng.uniform(0.5, 10.0))
    amp = float(rng.uniform(2.0, 7.0)) if amp is None else amp
    d0 = rng.uniform(0.3, 0.7)
    d1 = rng.uniform(0.15, 0.3)
    fd = rng.uniform(1 / 400, 1 / 120)
    ph = rng.uniform(0, 6.28)
    duty = np.clip(d0 + d1 * np.sin(2 * np.pi * fd * t + ph), 0.05, 0.95)
    phase = (t % period) / period
    U = np.where(phase < duty, amp, 0.0)
    return U, dict(kind="pwm", period_s=period, amp_V=amp, duty_mean=float(d0), duty_amp=float(d1), duty_freq_hz=float(fd))


def drive_multisine(rng, t, umax=None):
    m = int(rng.integers(3, 7))
    f = rng.uniform(1 / 300, 1 / 15, m)
    ph = rng.uniform(0, 2 * np.pi, m)
    A = rng.uniform(0.3, 1.0, m)
    s = sum(A[i] * np.sin(2 * np.pi * f[i] * t + ph[i]) for i in range(m))
    umax = float(rng.uniform(4.0, 7.0)) if umax is None else umax
    lo = float(rng.uniform(0.0, 1.5))
    U = lo + (s - s.min()) / (s.max() - s.min()) * (umax - lo)
    return U, dict(kind="multisine", n=m, freqs_hz=f.tolist(), amps=A.tolist(), umin_V=lo, umax_V=umax)


def drive_steps(rng, t, umax=None):
    umax = float(rng.uniform(4.0, 7.0)) if umax is None else umax
    U = np.empty_like(t)
    i = 0
    levels = []
    while i < len(t):
        hold = rng.uniform(5.0, 60.0)
        lev = rng.uniform(0.0, umax)
        j = np.searchsorted(t, t[i] + hold)
        U[i:j] = lev
        levels.append((float(t[i]), float(lev)))
        i = max(j, i + 1)
    U[0] = max(U[0], 0.5)  # power on at t=0
    return U, dict(kind="steps", umax_V=umax, n_levels=len(levels))


def add_excursion(rng, t, U, info):
    n = len(t)
    n70 = int(0.7 * n)
    umax70 = U[:n70].max()
    L = rng.uniform(20.0, 60.0)
    t0 = rng.uniform(t[n70] + 5, t[-1] - L - 5)
    lev = umax70 * rng.uniform(1.10, 1.20)
    m = (t >= t0) & (t < t0 + L)
    if info["kind"] == "pwm":
        U = U.copy()
        U[m] = np.where(U[m] > 0, lev, 0.0)
    else:
        U = U.copy()
        U[m] = lev
    info = dict(info, excursion=dict(t0=float(t0), length_s=float(L), level_V=float(lev), umax70_V=float(umax70)))
    return U, info


def make_record(plant_seed, drive_seed, drive, fs, minutes, sensor="displacement", start="cold", excursion=False, sees=None):
    p = draw_plant(plant_seed, sees)
    rng = np.random.default_rng(drive_seed)
    dt = 1.0 / fs
    t = np.arange(int(round(minutes * 60 * fs))) * dt
    U, info = {"pwm": drive_pwm, "multisine": drive_multisine, "steps": drive_steps}[drive](rng, t)
    if excursion:
        U, info = add_excursion(rng, t, U, info)
    T0 = None
    F0 = None
    if start == "warm":
        tp = np.arange(int(rng.uniform(180, 360) * fs)) * dt
        Up, _ = drive_steps(rng, tp, umax=float(U.max()))
        _, Tp, _, F0 = simulate(p, Up, dt)
        T0 = float(Tp[-1])
    y, T, x, _ = simulate(p, U, dt, T0, F0)
    sd = float(rng.uniform(0.002, 0.02))
    q = float(rng.choice([0.0001, 0.0005, 0.001]))
    q = min(q, sd / 2)
    offset = float(rng.uniform(10, 80)) if sensor == "length" else 0.0
    if os.environ.get("PLANT_C_OFFSET"):  # same mounted sensor as an earlier run
        offset = float(os.environ["PLANT_C_OFFSET"])
    clean = (offset - y) if sensor == "length" else y
    meas = np.round((clean + rng.normal(0, sd, len(t))) / q) * q
    meta = dict(
        plant=p,
        drive=info,
        fs=fs,
        minutes=minutes,
        sensor=sensor,
        offset_mm=offset,
        start=start,
        T0=T0 if T0 is not None else p["T_amb"],
        noise_sd=sd,
        quantum=q,
        plant_seed=plant_seed,
        drive_seed=drive_seed,
        x_range=[float(x.min()), float(x.max())],
    )
    return t, U, meas, clean, meta


def write_csv(path, t, U, yv, col="displacement_mm"):
    with open(path, "w") as f:
        f.write(f"time_s,voltage_V,{col}\n")
        for a, b, c in zip(t, U, yv):
            f.write(f"{a:.4f},{b:.4f},{c:.5f}\n")


if __name__ == "__main__":
    # usage: plant_c.py NAME plant_seed drive_seed drive fs minutes sensor start excursion(0/1) [sees]
    name, ps, ds, drive, fs, mins, sensor, start, exc = sys.argv[1:10]
    sees = sys.argv[10] if len(sys.argv) > 10 else None
    t, U, meas, clean, meta = make_record(int(ps), int(ds), drive, float(fs), float(mins), sensor, start, bool(int(exc)), sees)
    col = "length_mm" if sensor == "length" else "displacement_mm"
    meta["column"] = col
    n70 = int(0.7 * len(t))
    write_csv(f"{name}_whole.csv", t, U, meas, col)
    write_csv(f"{name}_first70.csv", t[:n70], U[:n70], meas[:n70], col)
    np.save(f"{name}_clean.npy", clean)
    json.dump(meta, open(f"{name}_meta.json", "w"), indent=1)
    print(
        json.dumps({k: meta[k] for k in ("noise_sd", "quantum", "offset_mm", "start", "x_range")}),
        f"tau={meta['plant']['tau']:.1f} sees={meta['plant']['sees']} n_ops={len(meta['plant']['r'])} "
        f"stroke={meta['plant']['stroke_mm']:.2f}",
    )
