"""Independent reference plants with a directly measured hysteresis input (plain numpy, no smafl_jax import).

Records as a user of a temperature- or pressure-driven actuator makes them: the input is the measured
stimulus itself (a temperature in C, a pressure), the output a length or displacement with sensor noise.
Three structures, none of them built from the toolkit's classes, each drawn at random:

- ``play``: a few play (backlash) operators with random thresholds, each with its own up and down
  slope scale (a tilted band, written here as an up and a down envelope), non-negative weights and a
  cubic of the input;
- ``preisach``: a continuous Preisach density (a sum of one to three 2-D Gaussians in (up, down)
  switching thresholds) on a fine 60 x 60 relay grid, plus a linear term;
- ``bouc_wen``: the rate-independent Bouc-Wen differential model ``dz = A dx - beta |dx| |z|^(n-1) z -
  gamma dx |z|^n`` integrated in 20 sub-steps per sample, plus a linear term (neither an operator sum nor a
  relay sum).

Every record starts at the lowest input with the plant's memory saturated from below (an actuator at
ambient), one sample at a time.  Drives: ``forc`` (first-order reversal curves), ``levels`` (random levels
joined by ramps, with holds), ``triangles`` (random amplitude and centre), ``sines`` (a slow multisine),
``steps`` (random steps).  ``orientation=-1`` is a length sensor (the output falls on contraction).
"""

from __future__ import annotations

import numpy as np

PLANTS = ("play", "preisach", "bouc_wen")
DRIVES = ("forc", "levels", "triangles", "sines", "steps")


def draw_plant(kind: str, rng: np.random.Generator) -> dict:
    """Random structure of one plant of ``kind`` on the unit input range [0, 1]."""
    if kind == "play":
        n = int(rng.integers(3, 9))
        return {
            "kind": kind,
            "r": np.sort(rng.uniform(0.0, 0.35, n)),
            "up": rng.uniform(0.6, 1.4, n),  # slope of the ascending envelope
            "down": rng.uniform(0.6, 1.4, n),
            "w": rng.gamma(2.0, 1.0, n),
            "poly": rng.normal(0.0, 0.3, 3),
        }
    if kind == "preisach":
        k = int(rng.integers(1, 4))
        return {
            "kind": kind,
            "mu": rng.uniform([0.35, 0.05], [0.95, 0.6], (k, 2)),  # (up, down) threshold centres, up > down mostly
            "sd": rng.uniform(0.05, 0.2, (k, 2)),
            "amp": rng.uniform(0.5, 1.5, k),
            "lin": float(rng.uniform(0.0, 0.5)),
        }
    if kind == "bouc_wen":
        return {
            "kind": kind,
            "A": float(rng.uniform(2.0, 6.0)),
            "beta": float(rng.uniform(2.0, 8.0)),
            "gamma": float(rng.uniform(-1.0, 1.0)),
            "n": float(rng.choice([1.0, 1.5, 2.0])),
            "lin": float(rng.uniform(0.1, 1.0)),
            "gain": float(rng.uniform(0.5, 2.0)),
        }
    raise ValueError(f"unknown plant {kind!r}; choose one of {PLANTS}")


def make_drive(family: str, n: int, rng: np.random.Generator) -> np.ndarray:
    """Unit-range drive (0 .. 1) of ``n`` samples, starting at 0."""
    out = [0.0]

    def ramp_to(level, steps):
        start = out[-1]
        out.extend(np.linspace(start, level, max(int(steps), 1) + 1)[1:].tolist())

    def hold(steps):
        out.extend([out[-1]] * max(int(steps), 0))

    while len(out) < n:
        if family == "forc":
            ramp_to(1.0, rng.integers(40, 120))
            for rev in np.sort(rng.uniform(0.0, 0.9, int(rng.integers(3, 7))))[::-1]:
                ramp_to(rev, rng.integers(20, 80))
                ramp_to(1.0, rng.integers(20, 80))
            ramp_to(0.0, rng.integers(40, 120))
        elif family == "levels":
            ramp_to(rng.uniform(0.0, 1.0), rng.integers(10, 80))
            hold(rng.integers(0, 60))
        elif family == "triangles":
            c, a = rng.uniform(0.2, 0.8), rng.uniform(0.1, 0.5)
            ramp_to(min(1.0, c + a), rng.integers(20, 100))
            ramp_to(max(0.0, c - a), rng.integers(20, 100))
        elif family == "sines":
            m = n - len(out)
            t = np.arange(1, m + 1)
            s = sum(rng.uniform(0.3, 1.0) * np.sin(2 * np.pi * t / rng.uniform(80, 600) + rng.uniform(0, 6.3)) for _ in range(3))
            s = (s - s.min()) / (np.ptp(s) + 1e-12)
            # join from the current value to the multisine smoothly
            w = np.clip(t / 100.0, 0.0, 1.0)
            out.extend(((1 - w) * out[-1] + w * s).tolist())
        elif family == "steps":
            out.append(float(rng.uniform(0.0, 1.0)))
            hold(rng.integers(20, 120))
        else:
            raise ValueError(f"unknown drive {family!r}; choose one of {DRIVES}")
    return np.clip(np.asarray(out[:n]), 0.0, 1.0)


def _play(p: dict, x: np.ndarray) -> np.ndarray:
    # z follows the band [down-envelope, up-envelope]: it is pushed up by x*up - r, down by x*down + r
    lo0, hi0 = p["up"] * x[0] - p["r"], p["down"] * x[0] + p["r"]
    z = np.maximum(lo0, hi0)  # descended to the first input: every operator on its upper (descending) envelope
    out = np.empty(x.size)
    for k, xk in enumerate(x):
        lo, hi = p["up"] * xk - p["r"], p["down"] * xk + p["r"]
        z = np.minimum(np.maximum(z, np.minimum(lo, hi)), np.maximum(lo, hi))
        out[k] = p["w"] @ z + p["poly"] @ np.array([xk, xk**2, xk**3])
    return out


def _preisach(p: dict, x: np.ndarray) -> np.ndarray:
    g = np.linspace(-0.1, 1.1, 60)
    A, B = np.meshgrid(g, g, indexing="ij")  # A: switch-up threshold, B: switch-down threshold
    keep = A > B
    dens = sum(
        a * np.exp(-0.5 * (((A - m[0]) / s[0]) ** 2 + ((B - m[1]) / s[1]) ** 2)) for a, m, s in zip(p["amp"], p["mu"], p["sd"])
    )
    a, b, w = A[keep], B[keep], dens[keep] / keep.sum() * 50.0
    state = -np.ones(a.size)  # all relays down: saturated from below
    out = np.empty(x.size)
    for k, xk in enumerate(x):
        state = np.where(xk >= a, 1.0, np.where(xk <= b, -1.0, state))
        out[k] = w @ state + p["lin"] * xk
    return out


def _bouc_wen(p: dict, x: np.ndarray) -> np.ndarray:
    z = -((p["A"] / (p["beta"] + abs(p["gamma"]) + 1e-9)) ** (1.0 / p["n"])) * 0.9  # near the lower saturation
    out = np.empty(x.size)
    prev = x[0]
    for k, xk in enumerate(x):
        dx = (xk - prev) / 20.0
        for _ in range(20):
            az = abs(z)
            z += p["A"] * dx - p["beta"] * abs(dx) * az ** (p["n"] - 1) * z - p["gamma"] * dx * az ** p["n"]
        prev = xk
        out[k] = p["gain"] * z + p["lin"] * xk
    return out


_OUTPUT = {"play": _play, "preisach": _preisach, "bouc_wen": _bouc_wen}


def make_record(
    seed: int,
    plant: str,
    drive: str,
    *,
    n: int = 4000,
    dt: float = 0.1,
    orientation: int = 1,
    noise: float = 0.005,
    u_lo: float | None = None,
    u_span: float | None = None,
    truth: dict | None = None,
) -> dict:
    """One noisy record: dict(t, u, y, y_clean, noise_sd, truth).  ``truth`` reuses a plant (a second run)."""
    rng = np.random.default_rng(seed)
    if truth is None:
        truth = {
            "plant": draw_plant(plant, rng),
            "u_lo": float(rng.uniform(15.0, 30.0)) if u_lo is None else float(u_lo),
            "u_span": float(rng.uniform(40.0, 80.0)) if u_span is None else float(u_span),
            "y_off": float(rng.uniform(-5.0, 25.0)),
            "y_scale": float(rng.uniform(0.5, 5.0)),
            "orientation": int(orientation),
        }
        # one scale per plant (not per record), from a full reversal-curve sweep: a second run stays the same plant
        ref = _OUTPUT[truth["plant"]["kind"]](truth["plant"], make_drive("forc", 2000, np.random.default_rng(0)))
        truth["raw_min"], truth["raw_ptp"] = float(ref.min()), float(np.ptp(ref)) + 1e-12
    x = make_drive(drive, n, rng)
    raw = _OUTPUT[truth["plant"]["kind"]](truth["plant"], x)
    y_clean = truth["y_off"] + truth["orientation"] * truth["y_scale"] * (raw - truth["raw_min"]) / truth["raw_ptp"]
    sd = noise * truth["y_scale"]
    y = y_clean + rng.normal(0.0, sd, n)
    return {
        "t": np.arange(n) * dt,
        "u": truth["u_lo"] + truth["u_span"] * x,
        "y": y,
        "y_clean": y_clean,
        "noise_sd": sd,
        "truth": truth,
    }


def write_csv(path, rec: dict) -> None:
    """CSV with time_s, temperature_C, length_mm (the input is a temperature: not a drive voltage)."""
    data = np.column_stack([rec["t"], rec["u"], rec["y"]])
    np.savetxt(path, data, delimiter=",", header="time_s,temperature_C,length_mm", comments="", fmt="%.9g")
