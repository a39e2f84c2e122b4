"""How far two equally good fits part on drives the record did not walk.

Why: `smafl fit` refines the operator memory at t = 0 two ways (by rule, and fitted per operator) and keeps the one
with the lower validation RMSE.  On records whose training part never walks some branches of the plant, the two fit
the training samples equally well and still predict new data very differently, and one validation block cannot tell
which is right.  Measured (session 48, independent plant A, 10-minute records, first 70 % fitted): the two variants
were 0.03-0.12 noise SD apart on the training samples of 6 records; held out they scored 36.4 vs 15.6x the noise
(PWM cold s47), 1.16 vs 10.5x (random levels s41), 4.07 vs 2.40x (PWM length s31), and 1.0-1.04x both on three
records.  On slow sweeps of the trained input range after the record they parted by 37.7, 10.3, 5.8 noise SD on the
first three and by 0.15, 0.27 and 35.2 on the others (the last held out well, but its held-out part does not sweep the
range).  The spread does not say which fit is right; it says how much the record leaves open.
"""

from __future__ import annotations

import numpy as np

from ..models._simulate import simulate

#: Triangle cycles over the trained input range in the probe drive.
SWEEPS = 3


def sweep_drive(u, n: int) -> np.ndarray:
    """``n`` samples of `SWEEPS` triangle cycles from the lowest to the highest value of ``u`` and back."""
    u = np.asarray(u, dtype=float)
    lo, hi = float(np.min(u)), float(np.max(u))
    phase = (np.arange(n) * SWEEPS / max(n, 1)) % 1.0
    return lo + (hi - lo) * (1.0 - np.abs(2.0 * phase - 1.0))


def sweep_spread(a, b, u, dt) -> dict:
    """Where models ``a`` and ``b`` part: each runs the input ``u`` (from its own start) and then `sweep_drive` of as
    many samples; the RMS and largest absolute difference of their outputs over the sweep samples."""
    u = np.asarray(u, dtype=float)
    probe = np.concatenate([u, sweep_drive(u, u.size)])
    d = np.asarray(simulate(a, probe, dt))[u.size :] - np.asarray(simulate(b, probe, dt))[u.size :]
    if not np.all(np.isfinite(d)):
        return {"rms": float("inf"), "max": float("inf"), "samples": int(u.size), "sweeps": SWEEPS}
    return {"rms": float(np.sqrt(np.mean(d**2))), "max": float(np.max(np.abs(d))), "samples": int(u.size), "sweeps": SWEEPS}
