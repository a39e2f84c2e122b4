"""Data checks: find faults in records before they are fitted (`check_record`, `check_records`).

Every rule is scale-free: sizes are compared with the record's own noise
scale, its own range or its own sample-to-sample changes, never with a number
in the data's units, so a record in mm, in volts or in raw counts (and at any
sample time) is judged alike.  The constants below are fixed a priori (from the
false-alarm rate of Gaussian noise and from what a fault does to a fit), not
tuned to any file.

Scales (per column):

- *range* R: 1st to 99th percentile (a few spikes cannot inflate it).
- *noise* sigma: 1.4826 MAD of the second differences / sqrt(6) (second
  differences remove smooth trends; the MAD ignores spikes and jumps); when
  more than half of them are zero (quantised or flat data) the mean absolute
  deviation is used instead.

Detectors on one record (`check_record`):

- ``constant``: the input or the output never changes (action ``drop``; the
  other detectors are then skipped).
- ``offset_jump`` (output; a sensor zeroed, knocked or re-seated while the
  input holds).  Rule: the median of the ``JUMP_WINDOW`` (10) samples after
  sample k differs from the median of the 10 samples up to k by at least
  ``JUMP_Z`` (10) sigma and ``JUMP_REL`` (5 %) of R; the change is a step (at
  most 2 samples between 25 % and 75 % of the way); each side is a level (the
  medians of its two halves differ by at most ``LEVEL_DRIFT`` (30 %) of the
  step: no fast ramp into a limit); and the input holds (its window medians
  differ by at most ``QUIET_REL`` (2 %) of its range, its median-filtered trace
  stays within 4 % of its range, and at most ``QUIET_OFF`` (10 %) of its samples
  lie more than 4 % of its range off the windows' median: the pulses of a PWM
  drive at a low duty are not a hold).  Output spikes are bridged first (a spike in a
  window biases its median); steps across a sampling gap of kept irregular
  stamps are skipped (``gap`` covers them).  The finding covers the shorter
  side of the step (up to the neighbouring step); the steps into and out of one
  offset stretch make one finding.  Action: ``cut`` when that side reaches the
  start or end of the record, else ``mark``.
- ``spike`` (input and output).  Rule: the residual of a 7-sample running
  median (a high-pass that keeps steps) exceeds ``SPIKE_Z`` (8) robust scales
  (1.4826 MAD of the residual; Gaussian false alarms ~1e-15 per sample) and
  ``SPIKE_REL`` (1 %) of R, over at most 3 samples; straight lines through the
  4 samples before and the 4 after both miss the excursion on the side the
  running median does (a peak of a triangle, a corner or a rounded peak is
  predicted by at least one side), by more than 8 x 2 sigma, 1 % of R and
  ``SPIKE_LOCAL`` (3) times the neighbours' own median sample-to-sample change
  (a sharp but smooth transient of a fast signal is not a spike).  The first
  and last two samples are not judged.  On the input, an excursion that peaks
  within 1 % of R of a level the drive dwells at (at least ``DRIVE_LEVEL``
  (5 %) of its samples within 1 % of R) is switching, not a fault: a PWM pulse
  of 1-3 samples at a low or high duty looks like a spike and is part of the
  drive.  Action: ``mark``.
- ``glitch`` (a measured input, and the output; a sensor reading an implausible
  value for seconds: a loose thermocouple at 86-220 C while the wire is at
  27-60 C).  Rule: a stretch of more than ``SPIKE_MAX_LEN`` (3) samples and at
  most ``GLITCH_MAX_FRAC`` (a quarter) of the record (the rest must be the
  record, to tell what is normal), entered and left by jumps of opposite sign,
  each at least ``GLITCH_Z`` (10) robust step scales (1.4826 MAD of the first
  differences) and ``GLITCH_REL`` (10 %) of R; its median lies beyond the
  medians of the 10 samples before and after it by at least that jump
  threshold, with ``GLITCH_INSIDE`` (80 %) of its samples beyond both.  The
  overlapping such stretches of one erratic fault are one block.  Then the
  block must lie beyond the range of the rest of the record (0.5..99.5
  percentiles of the record without all such blocks, then again without only
  the blocks kept): its median by at least the jump threshold and
  ``GLITCH_OUT`` (a quarter) of that range, 80 % of its samples beyond it (a
  level the record visits elsewhere is a level it was driven to).  A column
  with more than ``GLITCH_MAX_JUMPS`` (100) such jumps, kept blocks over more
  than a quarter of it, or more than ``GLITCH_FEW`` (3) of them is switching
  between levels (PWM, a staircase), not faulty: no finding.  Last, a block
  must read unlike the sensor: erratic (its mean absolute first difference
  more than ``GLITCH_ROUGH`` (3) times the rest of the record's: a loose
  contact) or frozen (its typical step, 1.4826 MAD of its first differences,
  under a third of the rest's: a stuck reading); a block that reads like the
  rest is the signal driven to another level (a heating pulse, the lowest step
  of a staircase), and a smooth offset of a measured input is not told from
  one.  A drive voltage (by name
  or unit) is not searched: a commanded drive may hold any level for any time
  (the bundled ``steps`` record's 7.4 V step between 5 V and 4 V would be a
  block); nor is an output edge at which the input changes by 10 % of its range
  (a fast system following its drive), nor a block an ``offset_jump`` already
  covers.  Spikes inside a block are not listed apart.  Action: ``cut`` when
  the record on one side of it is under ``CUT_SIDE`` (10 %), else ``mark``; as
  an input it also sets the model's state after it (bridge it or cut there).
- ``clipped`` (output).  Rule: the record's minimum or maximum value is held by
  at least ``FLAT_MIN`` (10) samples and ``CLIP_FACTOR`` (5) times as many as
  the typical distinct value, and at least 10 other samples lie within 5 % of
  R of it (the signal approaches the limit, as a clipped signal does; an
  isolated stuck value does not).  A limit the output sits at when the input
  is at its lowest (at least half of the samples within 1 % of R_u of the
  input's minimum) and whose samples mostly have a low input (their median in
  the lower ``REST_HALF`` (half) of the input's range) is the actuator at rest
  (an SMA wire below its activation voltage), not a sensor limit: no finding
  (and no ``flat`` on it).  A sensor floor reached while the input is low reads
  the same way and is not told from rest.  Action: ``mark`` the samples at that
  value.
- ``flat`` (output; a stuck sensor or a held value).  Rule: a run of exactly
  repeated values of at least 10 samples that is improbable for this record:
  with p the fraction of steps that repeat a value anywhere in the record, a
  run of L samples is flagged when n p^(L-1) < ``FLAT_P`` (1e-3, the expected
  number of such runs by chance); runs at a clipped limit are left to
  ``clipped``.  A stuck sensor that lets go while the input holds also gives an
  ``offset_jump`` at the end of the run.  Action: ``cut`` when the run touches
  the start or end, else ``mark``.
- ``irregular_sampling`` and ``gap``.  Rule: time steps off the median step by
  more than ``dt_rtol`` (15 %; kept irregular stamps: action ``resample``), or
  intervals bridged by resampling (`Record.gaps`: action ``mark``: the
  interpolated samples are not measurements); a repeated gap spacing is named
  as bursts.  Each gap of at least ``LONG_GAP_STEPS`` (10) sample times is also
  listed on its own: ``cut`` when the record on one side of it is under
  ``CUT_SIDE`` (10 %) of the record, else ``mark``; but when at least
  ``PERIODIC_GAPS`` (5) long gaps start at a regular spacing (80 % within
  ``PERIODIC_RTOL``, 20 %, of the median spacing) they are the logger's
  rhythm: said once in the sampling finding, and only those over twice the
  median long gap are listed (cutting before one of a rhythm's gaps removes a
  burst, not a fault).

- ``gap_input`` (input; sampling gaps that hide the drive).  Rule: on the
  time stamps as read (a resampled record's `Record.as_read`), a gap (a step
  that misses at least one sample: 1.5 sample times or more) "hides" a change of the input when the
  input differs by more than ``GAP_INPUT_REL`` (10 %) of its range across it,
  or, with probability 1 - (1 - p)^m, when the input moves that much in a
  fraction p of the ordinary steps and the gap misses m samples (a PWM edge
  falls into a gap as often as into any m steps).  Flagged when the expected
  fraction of such gaps is at least ``GAP_INPUT_FRAC`` (10 %): the resampled
  input is a straight line there, not the drive the actuator saw, and every
  fit and score after such a gap carries that error (a true plant driven by
  the interpolated input scores far above the noise).  Action: ``check``.
- ``sample_time`` (plausibility, the one rule in physical units): a sample
  time above ``SLOW_DT_S`` (5 s) on a record of more than ``SLOW_MIN_SAMPLES``
  (1000) samples driven by a voltage (thermal time constants of seconds, so a
  logger samples in ms): most likely millisecond stamps in a column read as
  seconds, and a fit then finds every rate 1000x too slow.  Action: ``check``.
  (A slow clock on a short record, such as the 642-sample SMA wing record at
  10 s, is not flagged.)

Across records (`check_records`):

- ``level_mismatch``: in 5 equal bins of the input band all records share
  (1st..99th percentiles), a record's output medians differ from the median
  record's in every bin with data by at least ``LEVEL_REL`` (25 %) of the
  median output range, all with one sign: a whole run shifted (a gain or
  hysteresis difference moves some bins, not all of them by a quarter of the
  range the same way).  With two records the odd one cannot be told; both are
  named.  Action: ``drop`` (or subtract the offset).
- ``input_range``: more than ``RANGE_OUT`` (10 %) of a record's input lies
  outside the others' band (0.5..99.5 percentiles, widened by 2 % of its span;
  with three or more others the band ``RANGE_COVER`` (2) of them reach: from
  the second-lowest low to the second-highest high, so that one faulty record's
  range does not hide another's fault),
  or its span is under ``RANGE_SPAN`` (half) the others' median span: a model
  trained on the others extrapolates there.  Action: ``check``.
- ``dt_mismatch`` (``resample``): sample times are grouped (within
  ``dt_rtol``); when one group holds more than half of the records, each record
  outside it is flagged against that group's sample time (one a record has);
  otherwise every record is flagged, with the list of sample times.
- ``duplicate`` (same file content: ``drop``).

Actions: ``cut`` (remove samples at the start or end), ``drop`` (leave the
record out), ``mark`` (keep simulating through them, leave them out of the
loss and the scores), ``resample`` (load with ``--resample DT``), ``check``
(look at it; no automatic remedy).  ``Finding.size`` is signed where a direction
exists: the offset of the affected stretch against the rest (jumps), the
excursion (spikes), the held value minus the record's median (flat, clipped),
the gap length in seconds (gaps), the block's median minus the nearer of the
levels before and after it (glitch).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from .names import is_voltage
from .record import DEFAULT_DT_RTOL, GAP_STEPS, Record

__all__ = ["Finding", "check_record", "check_records", "ACTIONS"]

ACTIONS = ("cut", "drop", "mark", "resample", "check")

JUMP_WINDOW = 10
JUMP_Z = 10.0
JUMP_REL = 0.05
QUIET_REL = 0.02
QUIET_OFF = 0.1
LEVEL_DRIFT = 0.3
SPIKE_WINDOW = 7
SPIKE_Z = 8.0
SPIKE_REL = 0.01
SPIKE_MAX_LEN = 3
SIDE_POINTS = 4
SPIKE_LOCAL = 3.0
DRIVE_LEVEL = 0.05
SIDE_NOISE = 2.0  # noise of a 4-point line extrapolated 1-3 steps, in units of the sample noise (about 1.6-2.2)
FLAT_MIN = 10
FLAT_P = 1e-3
CLIP_FACTOR = 5.0
LONG_GAP_STEPS = 10
CUT_SIDE = 0.1
LEVEL_REL = 0.25
LEVEL_BINS = 5
RANGE_OUT = 0.1
RANGE_SPAN = 0.5
RANGE_TOL = 0.02
SLOW_DT_S = 5.0
SLOW_MIN_SAMPLES = 1000
GLITCH_Z = 10.0
GLITCH_REL = 0.1
GLITCH_MAX_FRAC = 0.25
GLITCH_INSIDE = 0.8
GLITCH_OUT = 0.25
GLITCH_FEW = 3
GLITCH_ROUGH = 3.0
GLITCH_MAX_JUMPS = 100
REST_HALF = 0.5
RANGE_COVER = 2
GAP_INPUT_REL = 0.1
GAP_INPUT_FRAC = 0.1
PERIODIC_GAPS = 5
PERIODIC_RTOL = 0.2


@dataclasses.dataclass(frozen=True)
class Finding:
    """One suspected fault: where (record, column, time, samples), how large, and what to do."""

    kind: str
    record: str
    column: str
    time_s: tuple[float, float]
    index: tuple[int, int]  # [start, stop) sample indices of the affected stretch
    size: float  # in the column's units (signed where a direction exists); nan when not a size
    size_rel: float  # size / the column's range (1st..99th percentile)
    message: str
    action: str

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["time_s"], d["index"] = list(self.time_s), list(self.index)
        for k in ("size", "size_rel"):
            d[k] = None if not math.isfinite(d[k]) else float(d[k])
        return d

    def line(self, unit: str = "") -> str:
        """One-line text: record, kind, column, time, samples, size, action, message."""
        t0, t1 = self.time_s
        where = f"t {t0:.6g}-{t1:.6g} s" if t1 != t0 else f"t {t0:.6g} s"
        size = ""
        if math.isfinite(self.size):
            size = f"  size {self.size:+.4g}{' ' + unit if unit else ''}"
            if math.isfinite(self.size_rel):
                size += f" ({100 * self.size_rel:+.1f} % of range)"
        return (
            f"{self.record}  {self.kind}  [{self.column}]  {where} (samples {self.index[0]}..{self.index[1] - 1}){size}  "
            f"-> {self.action}: {self.message}"
        )


# -- scales -------------------------------------------------------------------------


def robust_range(x: np.ndarray) -> float:
    """1st to 99th percentile span (max - min when that is zero; nan for a constant column)."""
    x = np.asarray(x, float)
    lo, hi = np.percentile(x, [1, 99])
    r = float(hi - lo) or float(np.ptp(x))
    return r if r > 0 else math.nan


def noise_scale(x: np.ndarray, measured: np.ndarray | None = None) -> float:
    """Robust noise standard deviation from second differences (see module docstring).

    ``measured``: boolean mask of the samples that were measured; a second difference is used only when its three
    samples all are (interpolated stretches are straight lines, with no noise to see).
    """
    d2 = np.diff(np.asarray(x, float), 2)
    if measured is not None:
        m = np.asarray(measured, bool)
        d2 = d2[m[:-2] & m[1:-1] & m[2:]]
    if d2.size < 3:
        return 0.0
    dev = np.abs(d2 - np.median(d2))
    s = 1.4826 * float(np.median(dev))
    if s == 0.0:
        s = 1.2533 * float(np.mean(dev))
    return s / math.sqrt(6.0)


def noise_scale_on_stamps(t: np.ndarray, x: np.ndarray, max_step: float) -> float:
    """`noise_scale` on irregular time stamps: each sample's distance from the straight line through its two
    neighbours, scaled to the noise SD (variance (1 + a^2 + b^2) sigma^2 for interpolation weights a, b; on a
    uniform grid this is the second difference / -2).  A line has no residual, so a slope between jittered stamps
    adds none; triples with a step over ``max_step`` (a gap, where the signal moves) or a non-finite value are left
    out."""
    t, x = np.asarray(t, float), np.asarray(x, float)
    if t.size < 5:
        return 0.0
    d0, d1 = np.diff(t)[:-1], np.diff(t)[1:]
    a = d1 / (d0 + d1)  # weight of the left neighbour in the line through both at t[k]
    r = (x[1:-1] - (a * x[:-2] + (1 - a) * x[2:])) / np.sqrt(1 + a**2 + (1 - a) ** 2)
    r = r[(d0 <= max_step) & (d1 <= max_step) & np.isfinite(r)]
    if r.size < 3:
        return 0.0
    dev = np.abs(r - np.median(r))
    s = 1.4826 * float(np.median(dev))
    return s if s > 0 else 1.2533 * float(np.mean(dev))


def _medfilt(x: np.ndarray, w: int) -> np.ndarray:
    h = w // 2
    if x.size <= h:
        return np.full_like(x, np.median(x))
    return np.median(sliding_window_view(np.pad(x, h, mode="reflect"), w), axis=1)


def _runs(flag: np.ndarray) -> list[tuple[int, int]]:
    """``[start, stop)`` of the runs of True in a boolean array."""
    f = np.concatenate([[False], np.asarray(flag, bool), [False]])
    edges = np.flatnonzero(np.diff(f.astype(np.int8)))
    return list(zip(edges[0::2].tolist(), edges[1::2].tolist()))


def _finding(rec, kind, column, a, b, size, rng, message, action) -> Finding:
    n = len(rec)
    a, b = max(0, int(a)), min(n, int(b))
    t = rec.time
    return Finding(
        kind=kind,
        record=rec.name,
        column=str(column),
        time_s=(float(t[a]), float(t[max(a, b - 1)])),
        index=(a, b),
        size=float(size),
        size_rel=float(size / rng) if math.isfinite(size) and rng and math.isfinite(rng) else math.nan,
        message=message,
        action=action,
    )


# -- single-record detectors ------------------------------------------------------------


def _side_prediction(t: np.ndarray, x: np.ndarray, idx: np.ndarray, at: np.ndarray) -> np.ndarray | None:
    """Least-squares line through ``x[idx]`` (over time) evaluated at ``t[at]``; None with fewer than 2 points."""
    if idx.size < 2:
        return None
    tt = t[idx] - t[idx].mean()
    slope = float(tt @ (x[idx] - x[idx].mean()) / (tt @ tt))
    return x[idx].mean() + slope * (t[at] - t[idx].mean())


def _dwell_level(xs: np.ndarray, value: float, rng: float) -> bool:
    """Whether at least ``DRIVE_LEVEL`` of the samples lie within ``SPIKE_REL`` of the range of ``value`` (``xs``:
    the samples sorted, so that a long PWM record with thousands of short pulses costs a search per pulse)."""
    lo = np.searchsorted(xs, value - SPIKE_REL * rng, side="left")
    hi = np.searchsorted(xs, value + SPIKE_REL * rng, side="right")
    return bool(hi - lo >= DRIVE_LEVEL * xs.size)


def _spikes(rec: Record, x: np.ndarray, column: str, drive: bool = False) -> list[Finding]:
    """Short excursions off the local trend on both sides; ``drive``: the column is the input (levels it dwells at are
    switching, not faults)."""
    rng = robust_range(x)
    n = x.size
    if n < SPIKE_WINDOW or not math.isfinite(rng):
        return []
    t = np.asarray(rec.time, float)
    xs = np.sort(x) if drive else None
    r = x - _medfilt(x, SPIKE_WINDOW)
    dev = np.abs(r - np.median(r))
    s = 1.4826 * float(np.median(dev)) or 1.2533 * float(np.mean(dev))
    sig = noise_scale(x)
    bad = (np.abs(r) > SPIKE_Z * s) & (np.abs(r) > SPIKE_REL * rng)
    out = []
    for a, b in _runs(bad):
        # the core of the excursion: samples at least half as far off as its peak, on its side (a wide spike on a slope
        # biases the running median, which can flag a neighbour weakly)
        peak = r[a + int(np.argmax(np.abs(r[a:b])))]
        core = np.flatnonzero(r[a:b] * np.sign(peak) >= 0.5 * abs(peak))
        a, b = a + int(core[0]), a + int(core[-1]) + 1
        if b - a > SPIKE_MAX_LEN or b - a != core.size:
            continue
        k = a + int(np.argmax(np.abs(r[a:b])))
        if drive and _dwell_level(xs, float(x[k]), rng):
            continue  # a short pulse of a switching drive (PWM at a low or high duty), not a fault
        # a spike leaves the local trend on both sides: a peak of a triangle or a corner is predicted by at least
        # one side's straight line, a spike by neither
        li, ri = np.arange(max(0, a - SIDE_POINTS), a), np.arange(b, min(n, b + SIDE_POINTS))
        if li.size < 2 or ri.size < 2:
            continue  # the first and last two samples cannot be told from a trend change
        res = [float(x[k] - _side_prediction(t, x, idx, np.array([k]))[0]) for idx in (li, ri)]
        if not all(e * r[k] > 0 for e in res):
            continue  # not off both trends the way it is off the running median
        size = min(res, key=abs)
        # the neighbours' own sample-to-sample changes: a sharp but smooth peak of a fast signal is not a spike
        local = float(np.median(np.abs(np.concatenate([np.diff(x[li]), np.diff(x[ri])]))))
        if abs(size) <= max(SPIKE_Z * SIDE_NOISE * sig, SPIKE_REL * rng, SPIKE_LOCAL * local):
            continue
        out.append(
            _finding(
                rec,
                "spike",
                column,
                a,
                b,
                size,
                rng,
                f"{b - a}-sample excursion of {abs(r[k]) / s:.0f} robust scales off the running median, off the local trend on both sides",
                "mark",
            )
        )
    return out


def step_scale(x: np.ndarray) -> float:
    """Robust typical sample-to-sample step: 1.4826 MAD of the first differences (the mean absolute deviation when
    more than half of them are equal: held or quantised data)."""
    d = np.diff(np.asarray(x, float))
    if d.size < 3:
        return 0.0
    dev = np.abs(d - np.median(d))
    return 1.4826 * float(np.median(dev)) or 1.2533 * float(np.mean(dev))


def _roughness(d: np.ndarray) -> tuple[float, float]:
    """Mean absolute sample-to-sample step ``d`` (large with the jumps of an erratic reading) and 1.4826 MAD of them
    (the typical step: 0 for a frozen reading, and for exact holds, so that two exact holds are alike)."""
    if not d.size:
        return 0.0, 0.0
    return float(np.mean(np.abs(d))), 1.4826 * float(np.median(np.abs(d - np.median(d))))


def _glitch_blocks(x: np.ndarray, gap_after: np.ndarray, other: np.ndarray | None) -> tuple[list, dict]:
    """``[(a, b, median, level before, level after, entry jump, exit jump, how it reads)]`` of the glitch blocks of
    ``x`` (rules in the module docstring) and the scales used; ``other``: the input when ``x`` is the output (an edge the input jumps
    with is the system following its drive)."""
    n = x.size
    rng = robust_range(x)
    w, side = JUMP_WINDOW, SIDE_POINTS
    if n < 4 * w or not math.isfinite(rng):
        return [], {}
    d = np.diff(x)
    thr = max(GLITCH_Z * step_scale(x), GLITCH_REL * rng)
    big = (np.abs(d) >= thr) & ~gap_after
    if other is not None:
        ru = robust_range(other)
        if math.isfinite(ru):
            # the input's change across each step (3 samples each side): a fast system steps with its drive
            m = np.median(sliding_window_view(np.pad(other, (2, 3), mode="edge"), 3), axis=1)  # m[k] = median(u[k-2..k])
            big &= np.abs(m[3:] - m[:-3])[: d.size] < GLITCH_REL * ru
    jumps = np.flatnonzero(big)
    if jumps.size < 2 or jumps.size > GLITCH_MAX_JUMPS:
        return [], {}  # no block, or a column that switches all the time (its blocks are its drive)
    max_len = int(GLITCH_MAX_FRAC * n)
    cands = []
    for ii, i in enumerate(jumps):
        a = int(i) + 1
        if a < side:
            continue
        s = 1.0 if d[i] > 0 else -1.0
        before = float(np.median(x[max(0, a - w) : a]))
        for j in jumps[ii + 1 :]:
            b = int(j) + 1
            if b - a > max_len:
                break
            if b - a <= SPIKE_MAX_LEN or d[j] * s > 0 or b > n - side:
                continue
            after = float(np.median(x[b : b + w]))
            level = float(np.median(x[a:b]))
            if s * (level - before) < thr or s * (level - after) < thr:
                continue
            # mostly beyond both sides: a stretch that runs on into the normal record after the fault is no block
            edge = max(before, after) if s > 0 else min(before, after)
            if float(np.mean(s * (x[a:b] - edge) > 0)) >= GLITCH_INSIDE:
                cands.append((a, b))
    if not cands:
        return [], {}
    cands.sort()
    unions = [list(cands[0])]
    for a, b in cands[1:]:
        if a < unions[-1][1]:
            unions[-1][1] = max(unions[-1][1], b)  # the sub-blocks of an erratic fault are one block
        else:
            unions.append([a, b])
    unions = [(a, b) for a, b in unions if b - a <= max_len]

    def beyond_rest(blocks):
        # the blocks whose level lies far beyond the record without ``blocks`` (and that band)
        rest = np.ones(n, bool)
        for a, b in blocks:
            rest[a:b] = False
        lo, hi = (float(v) for v in np.percentile(x[rest], [0.5, 99.5]))
        margin = max(thr, GLITCH_OUT * (hi - lo))
        keep = []
        for a, b in blocks:
            level = float(np.median(x[a:b]))
            up = level > hi
            beyond = x[a:b] > hi if up else x[a:b] < lo
            if (level - hi if up else lo - level) >= margin and float(np.mean(beyond)) >= GLITCH_INSIDE:
                keep.append((a, b))
        return keep, (lo, hi)

    # first against the record without every candidate (noise-sized ones on a rough plateau included), then again
    # against the record without the blocks kept: a staircase whose many steps were all candidates keeps none
    kept, _ = beyond_rest(unions)
    kept, (lo, hi) = beyond_rest(kept) if kept else ([], (math.nan, math.nan))
    if not kept or len(kept) > GLITCH_FEW or sum(b - a for a, b in kept) > max_len:
        return [], {}  # none, or many such blocks: the column is driven between levels, a fault is rare
    # a fault reads unlike the sensor: erratic (a loose contact) or frozen (a stuck reading); a block with the record's
    # own sample-to-sample roughness is the signal driven to another level (a heating pulse, a step of a staircase)
    inner = np.ones(d.size, bool)  # the steps between two samples of the rest (no block edge, no block inside)
    for a, b in kept:
        inner[max(0, a - 1) : b] = False
    rough, typical = _roughness(d[inner])
    out = []
    for a, b in kept:
        r, r_typ = _roughness(d[a : b - 1])
        erratic, frozen = r > GLITCH_ROUGH * rough, GLITCH_ROUGH * r_typ < typical
        if not (erratic or frozen):
            continue
        before, after = float(np.median(x[max(0, a - w) : a])), float(np.median(x[b : b + w]))
        if erratic:
            how = f"erratic (mean step {r / rough:.0f}x the rest's)" if rough > 0 else "erratic (the rest holds exact levels)"
        else:
            how = f"frozen (typical step {r_typ / typical:.2g}x the rest's)"
        out.append((a, b, float(np.median(x[a:b])), before, after, float(d[a - 1]), float(d[b - 1]), how))
    return out, {"thr": thr, "step": step_scale(x), "band": (lo, hi), "range": rng}


def _glitches(rec: Record, x: np.ndarray, column: str, dt_rtol: float, other: np.ndarray | None = None) -> list[Finding]:
    """Findings for stretches of seconds at an implausible level, entered and left by jumps (a sensor fault)."""
    t = np.asarray(rec.time, float)
    dts = np.diff(t)
    gap_after = dts > (1 + dt_rtol) * np.median(dts) if dts.size else np.zeros(0, bool)
    blocks, sc = _glitch_blocks(np.asarray(x, float), gap_after, other)
    n = x.size
    out = []
    for a, b, level, before, after, d_in, d_out, how in blocks:
        size = level - (before if abs(level - before) <= abs(level - after) else after)
        head, tail = a / n, (n - b) / n
        if min(head, tail) < CUT_SIDE:
            if head <= tail:
                what = f"cut t < {t[b]:.6g} s (the {a} samples before it and the block: --window {t[b]:.6g}:)"
            else:
                what = f"cut t > {t[a - 1]:.6g} s (the block and the {n - b} samples after it: --window :{t[a - 1]:.6g})"
            action = "cut"
        else:
            what, action = "leave these samples out of the loss and the scores", "mark"
        if other is None:
            what += "; as an input it also sets the model's state after it: bridge the input over it or cut the record there"
        lo, hi = sc["band"]
        out.append(
            _finding(
                rec,
                "glitch",
                column,
                a,
                b,
                size,
                sc["range"],
                f"{b - a} samples ({t[b - 1] - t[a]:.3g} s) at a median {level:.4g} against {before:.4g} before and "
                f"{after:.4g} after, entered by a jump of {d_in:+.4g} and left by {d_out:+.4g} (>= {sc['thr']:.3g}, "
                f"{sc['thr'] / sc['step']:.0f}x the typical step) and beyond the rest of the record's range "
                f"[{lo:.4g}, {hi:.4g}], {how}: a sensor fault, not a measured value; {what}",
                action,
            )
        )
    return out


def _input_quiet(u: np.ndarray, a: int, k: int, b: int) -> tuple[bool, float]:
    """Whether the input holds still over ``[a, b)`` around a step after ``k`` (and the relative change of its medians)."""
    ru = robust_range(u)
    if not math.isfinite(ru):
        return True, 0.0
    du = abs(float(np.median(u[k + 1 : b]) - np.median(u[a : k + 1]))) / ru
    mf = _medfilt(u[a:b], 5) if b - a >= 5 else u[a:b]
    # a PWM drive at a low duty has a flat median (the filter removes its pulses) but is not holding: the output moves
    # with its duty (measured: a clean 5 Hz PWM record flagged as a zeroed sensor); a few input spikes still hold
    off = float(np.mean(np.abs(u[a:b] - np.median(u[a:b])) > 2 * QUIET_REL * ru))
    return bool(du <= QUIET_REL and float(np.ptp(mf)) / ru <= 2 * QUIET_REL and off <= QUIET_OFF), du


def _step_at(y: np.ndarray, k: int, w: int) -> tuple[float, float]:
    """Medians of the ``w`` samples up to ``k`` and the ``w`` samples after it."""
    return float(np.median(y[max(0, k - w + 1) : k + 1])), float(np.median(y[k + 1 : k + 1 + w]))


def _jumps(rec: Record, dt_rtol: float, y: np.ndarray) -> list[Finding]:
    u = np.asarray(rec.u, float)
    n, w = y.size, JUMP_WINDOW
    dts = np.diff(np.asarray(rec.time, float))
    gap_after = dts > (1 + dt_rtol) * np.median(dts)  # irregular stamps kept: a step across missing time is no jump
    rng, sig = robust_range(y), noise_scale(y)
    if n < 2 * w or not math.isfinite(rng):
        return []
    med = np.median(sliding_window_view(y, w), axis=1)  # med[i] = median(y[i : i + w])
    ks = np.arange(w - 1, n - w)
    D = med[ks + 1] - med[ks - w + 1]
    thr = max(JUMP_Z * sig, JUMP_REL * rng)
    steps = []
    for a, b in _runs(np.abs(D) >= thr):
        k0 = int(ks[a + int(np.argmax(np.abs(D[a:b])))])
        lo0, hi0 = max(0, k0 - w + 1), min(n, k0 + w + 1)
        before, after = _step_at(y, k0, w)
        x = (y[lo0:hi0] - before) / (after - before)
        # the step sits where the fewest samples fall on the wrong side of the half-way level
        wrong = [int(np.sum(x[: j + 1] > 0.5) + np.sum(x[j + 1 :] < 0.5)) for j in range(x.size - 1)]
        k = lo0 + int(np.argmin(wrong))
        if k < w - 1 or k > n - w - 1 or gap_after[k]:
            continue
        before, after = _step_at(y, k, w)
        d = after - before
        if abs(d) < thr:
            continue
        lo, hi = k - w + 1, k + w + 1
        x = (y[lo:hi] - before) / d
        if int(np.sum((x > 0.25) & (x < 0.75))) > 2:
            continue  # a ramp, not a step
        h = w // 2
        drift = max(abs(float(np.median(x[h:w]) - np.median(x[:h]))), abs(float(np.median(x[w + h :]) - np.median(x[w : w + h]))))
        if drift > LEVEL_DRIFT:
            continue  # the sides are not levels (a fast ramp into a limit, say)
        quiet, du = _input_quiet(u, lo, k, hi)
        if quiet and (not steps or steps[-1][0] != k):
            steps.append((k, d, du))
    regions = []
    for i, (k, d, du) in enumerate(steps):
        # the shorter side of the step, up to the neighbouring step or the record end
        left = steps[i - 1][0] + 1 if i > 0 else 0
        right = steps[i + 1][0] + 1 if i + 1 < len(steps) else n
        if k + 1 - left <= right - (k + 1):
            regions.append((left, k + 1, -d, [(k, d, du)]))
        else:
            regions.append((k + 1, right, d, [(k, d, du)]))
    merged = []
    for reg in regions:
        if merged and merged[-1][:2] == reg[:2]:
            merged[-1][3].extend(reg[3])  # the steps into and out of one offset stretch
        else:
            merged.append(reg)
    out = []
    for a, b, size, parts in merged:
        at_end = a == 0 or b == n
        window = f"--window {rec.time[b]:.6g}:" if a == 0 else f"--window :{rec.time[a - 1]:.6g}"
        what = (
            f"cut the {b - a} samples {'before' if a == 0 else 'after'} the step ({window})"
            if at_end
            else f"mark samples {a}..{b - 1} (or subtract the offset)"
        )
        told = "; ".join(f"steps by {d:+.4g} between t = {rec.time[k]:.6g} and {rec.time[k + 1]:.6g} s" for k, d, _ in parts)
        du = max(p[2] for p in parts)
        out.append(
            _finding(
                rec,
                "offset_jump",
                rec.output_name,
                a,
                b,
                size,
                rng,
                f"output {told} while the input holds (its level changes {100 * du:.1f} % of its range): sensor zeroed or "
                f"moved, or driven by something not recorded; {what}",
                "cut" if at_end else "mark",
            )
        )
    return out


def _at_rest(u: np.ndarray, at: np.ndarray) -> bool:
    """Whether the output's samples ``at`` a limit are the actuator at rest: the output sits there at the input's
    lowest values (at least half of the samples within ``SPIKE_REL`` of the input's range of its minimum), and most of
    them (their median input) have the input in the lower ``REST_HALF`` of its range.  A clipped sensor while the input
    keeps rising (a flat at the maximum, the input high) is not rest."""
    ru = robust_range(u)
    if not math.isfinite(ru) or at.all():
        return False
    u0 = float(np.percentile(u, 1))
    lowest = u <= float(u.min()) + SPIKE_REL * ru
    return bool(np.mean(at[lowest]) >= 0.5 and float(np.median(u[at])) <= u0 + REST_HALF * ru)


def _clipped(rec: Record, y: np.ndarray, rng: float) -> tuple[list[Finding], set[float]]:
    """Findings for a record minimum/maximum the output sits on far more often than on other values."""
    n = y.size
    _, counts = np.unique(y, return_counts=True)
    typical = float(np.median(counts))
    out, limits = [], set()
    for name, v in (("minimum", float(y.min())), ("maximum", float(y.max()))):
        at = y == v
        m = int(at.sum())
        if m < max(FLAT_MIN, CLIP_FACTOR * typical) or v in limits:
            continue
        # a limit is approached: the signal spends time close to it; an isolated value (a stuck offset) is not
        near = int(np.sum(~at & (np.abs(y - v) <= JUMP_REL * rng)))
        if near < FLAT_MIN:
            continue
        limits.add(v)
        if _at_rest(np.asarray(rec.u, float), at):
            continue  # the actuator at rest (the drive low), not a sensor limit; no `flat` either
        runs = _runs(at)
        longest = max(runs, key=lambda r: r[1] - r[0])
        idx = np.flatnonzero(at)
        out.append(
            _finding(
                rec,
                "clipped",
                rec.output_name,
                idx[0],
                idx[-1] + 1,
                v - float(np.median(y)),
                rng,
                f"{m} samples ({m / n:.1%}) sit exactly at the record's {name} {v:.6g}, in {len(runs)} runs (the longest "
                f"{longest[1] - longest[0]} samples from t = {rec.time[longest[0]]:.6g} s): a sensor or processing limit; mark "
                "the samples at that value (if the actuator really rests there, keep them)",
                "mark",
            )
        )
    return out, limits


def _flats(rec: Record) -> list[Finding]:
    y, u = np.asarray(rec.y, float), np.asarray(rec.u, float)
    n = y.size
    if n < FLAT_MIN:
        return []
    rng, ru = robust_range(y), robust_range(u)
    out, limits = _clipped(rec, y, rng)
    eq = np.diff(y) == 0
    p = min(float(eq.mean()), 0.99)
    need = FLAT_MIN if p == 0 else max(FLAT_MIN, 1 + math.ceil(math.log(FLAT_P / n) / math.log(p)))
    lo, hi = float(y.min()), float(y.max())
    for a, b in _runs(eq):
        b += 1  # runs of equal steps -> [start, stop) of equal samples
        v = float(y[a])
        if b - a < need or v in limits:
            continue
        extreme = "minimum" if v == lo else ("maximum" if v == hi else None)
        move = float(np.ptp(u[a:b])) / ru if math.isfinite(ru) else 0.0
        inp = (
            "while the input is constant too (noise-free data?)"
            if move == 0
            else f"while the input spans {100 * move:.1f} % of its range"
        )
        why = f"at the record's {extreme}" if extreme else "inside the output's range"
        chance = n * p ** (b - a - 1)
        odds = f"{chance:.1e}" if chance > 1e-99 else "< 1e-99"
        out.append(
            _finding(
                rec,
                "flat",
                rec.output_name,
                a,
                b,
                v - float(np.median(y)),
                rng,
                f"output exactly {v:.6g} for {b - a} samples {why} {inp}: a stuck sensor or a held value "
                f"(expected number of chance runs this long {odds})",
                "cut" if (a == 0 or b == n) else "mark",
            )
        )
    return out


def _sampling(rec: Record, dt_rtol: float) -> list[Finding]:
    t = np.asarray(rec.time, float)
    n = t.size
    if n < 3:
        return []
    d = np.diff(t)
    med = float(np.median(d))
    irregular = np.abs(d - med) > dt_rtol * med
    if irregular.any():
        gaps = [(float(t[k]), float(t[k + 1])) for k in np.flatnonzero(d > (1 + dt_rtol) * med)]
        step = med
        kept = True
    elif rec.gaps:
        gaps, step, kept = list(rec.gaps), float(rec.dt), False
    else:
        return []
    out = []
    span = float(t[-1] - t[0]) or 1.0
    starts = np.array([g[0] for g in gaps])
    ends = np.array([g[1] for g in gaps])
    burst = ""
    if len(gaps) >= 3:
        runs = np.round((starts[1:] - ends[:-1]) / step).astype(int) + 1
        vals, counts = np.unique(runs, return_counts=True)
        if counts.max() >= 0.8 * runs.size:
            burst = f"; bursts of {int(vals[np.argmax(counts)])} samples"
    lengths = ends - starts if gaps else np.zeros(0)
    periodic = _periodic_long_gaps(starts, lengths, step)
    if periodic is not None:
        burst += (
            f"; {int(periodic.sum())} long gaps (>= {LONG_GAP_STEPS} sample times, median {np.median(lengths[periodic]):.3g} s) "
            f"come every {np.median(np.diff(starts[periodic])):.3g} s: a logger's rhythm, not listed one by one"
        )
    if kept:
        n_short = int(np.sum(irregular)) - len(gaps)
        msg = (
            f"{int(irregular.sum())} of {n - 1} steps off the median {med:.6g} s by more than {dt_rtol:.0%} ({len(gaps)} gap{'s' if len(gaps) != 1 else ''}"
            + (f" of {lengths.min():.3g}..{lengths.max():.3g} s" if gaps else "")
            + (f", {n_short} short steps" if n_short > 0 else "")
            + f"){burst}; models need a uniform grid: load with --resample {med:.6g} (linear interpolation, gaps reported)"
        )
        first = int(np.flatnonzero(irregular)[0])
        msg = f"first at t = {t[first]:.6g} s; " + msg
        out.append(_finding(rec, "irregular_sampling", "time_s", 0, n, math.nan, math.nan, msg, "resample"))
    else:
        grid_in_gap = int(np.sum(~rec.measured))
        msg = (
            f"resampled record: {len(gaps)} gap{'s' if len(gaps) != 1 else ''} of {lengths.min():.3g}..{lengths.max():.3g} s bridged by linear interpolation"
            f"{burst}; {grid_in_gap} of {n} samples ({grid_in_gap / n:.1%}) are interpolated, not measured: fit, diagnose and their scores give them no weight"
        )
        out.append(_finding(rec, "irregular_sampling", "time_s", 0, n, math.nan, math.nan, msg, "mark"))
    out += _gap_input(rec, step)
    for i, ((a_t, b_t), L) in enumerate(zip(gaps, lengths)):
        if L < LONG_GAP_STEPS * step or (periodic is not None and periodic[i]):
            continue  # short, or one of the logger's rhythm (said once in the sampling finding)
        # the samples strictly inside the gap (interpolated ones); kept stamps have none: then the two around it
        a = int(np.searchsorted(t, a_t, side="right"))
        b = int(np.searchsorted(t, b_t, side="left"))
        if b <= a:
            a, b = a - 1, b + 1
        head, tail = (a_t - t[0]) / span, (t[-1] - b_t) / span
        if min(head, tail) < CUT_SIDE:
            if head <= tail:
                b = int(np.searchsorted(t, b_t, side="left"))
                a, what = 0, f"cut t < {b_t:.6g} s ({b} samples: the {100 * head:.1f} % of the record before the gap and the gap)"
            else:
                a = int(np.searchsorted(t, a_t, side="right"))
                b, what = n, f"cut t > {a_t:.6g} s ({n - a} samples: the gap and the {100 * tail:.1f} % of the record after it)"
            action = "cut"
        else:
            what, action = "simulate through it, leave it out of the scores", "mark"
        out.append(
            _finding(
                rec,
                "gap",
                "time_s",
                a,
                b,
                L,
                math.nan,
                f"{'no samples' if kept else 'bridged by interpolation'} for {L:.4g} s ({L / step:.0f} sample times) from t = {a_t:.6g} s; {what}",
                action,
            )
        )
    return out


def _periodic_long_gaps(starts: np.ndarray, lengths: np.ndarray, step: float) -> np.ndarray | None:
    """Mask of the long gaps that are a logger's rhythm (module docstring, ``gap``), or None when they are not one."""
    long = lengths >= LONG_GAP_STEPS * step
    if long.sum() < PERIODIC_GAPS:
        return None
    spacing = np.diff(starts[long])
    regular = np.abs(spacing - np.median(spacing)) <= PERIODIC_RTOL * np.median(spacing)
    if regular.mean() < 0.8:
        return None
    return long & (lengths <= 2 * np.median(lengths[long]))


def _gap_input(rec: Record, step: float) -> list[Finding]:
    """``gap_input`` (module docstring): gaps in the stamps as read across or inside which the input changes."""
    raw = rec if rec.as_read is None and not rec.gaps else rec.as_read
    if raw is None:  # resampled without its stamps as read: nothing to judge the gaps by
        return []
    t, u = np.asarray(raw.time, float), np.asarray(raw.u, float)
    rng = robust_range(rec.u)
    d = np.diff(t)
    gap = d >= GAP_STEPS * step  # a step that misses a sample; a jittered step hides nothing
    if not gap.any() or not math.isfinite(rng) or (~gap).sum() < 10:
        return []
    moves = np.abs(np.diff(u)) > GAP_INPUT_REL * rng
    p = float(moves[~gap].mean())
    missed = np.round(d[gap] / step) - 1
    hides = np.where(moves[gap], 1.0, 1.0 - (1.0 - p) ** missed)
    frac = float(hides.mean())
    if frac < GAP_INPUT_FRAC:
        return []
    k_gap = np.flatnonzero(gap)
    across = np.abs(np.diff(u))[gap]
    likely = k_gap[hides >= 0.5] if (hides >= 0.5).any() else k_gap
    a = int(np.searchsorted(rec.time, t[likely[0]], side="left"))
    b = int(np.searchsorted(rec.time, t[likely[-1] + 1], side="right"))
    n_across = int(moves[gap].sum())
    return [
        _finding(
            rec,
            "gap_input",
            rec.input_name,
            a,
            b,
            float(across.max()),
            rng,
            f"about {frac:.0%} of the {gap.sum()} sampling gaps (median {np.median(d[gap]):.3g} s) hide or straighten a "
            f"change of the input: it differs by more than {GAP_INPUT_REL:.0%} of its range across {n_across} of them (up "
            f"to {across.max():.4g}), and it moves that much in {p:.1%} of the ordinary steps, so a gap of "
            f"{int(np.median(missed))} missing samples misses such a move with probability "
            f"{1 - (1 - p) ** np.median(missed):.0%}. Across a gap the resampled input is a straight line, not the drive the "
            "actuator saw: every fit and score after such a gap carries that error, and a fit cannot tell it from misfit. "
            "Log faster than the drive changes (or log its set-points), or fit a stretch without gaps",
            "check",
        )
    ]


def _slow_clock(rec: Record) -> list[Finding]:
    """A long drive-voltage record sampled slower than `SLOW_DT_S`: millisecond stamps read as seconds?"""
    n = len(rec)
    if not (rec.dt > SLOW_DT_S and n > SLOW_MIN_SAMPLES and is_voltage(rec.input_name, rec.units)):
        return []
    col = getattr(rec, "time_name", "time_s")
    hours = (float(rec.time[-1]) - float(rec.time[0])) / 3600
    return [
        _finding(
            rec,
            "sample_time",
            "time_s",
            0,
            n,
            float(rec.dt),
            math.nan,
            f"sample time {rec.dt:.6g} s over {n} samples ({hours:.3g} h) for a drive voltage, whose thermal time constants "
            f"are seconds: is '{col}' in milliseconds? If so, say so (a column named time_ms or 'time [ms]', or the "
            f'sidecar\'s "units": {{"{col}": "ms"}}) and load again; read as seconds, a fit finds every rate 1000x too slow',
            "check",
        )
    ]


def _inside_none(found: list[Finding], blocks: list[Finding]) -> list[Finding]:
    """``found`` without the findings inside a block of the same column (a glitch block's own spikes)."""
    return [
        f
        for f in found
        if not any(g.column == f.column and g.index[0] <= f.index[0] and f.index[1] <= g.index[1] for g in blocks)
    ]


def check_record(record: Record, *, dt_rtol: float = DEFAULT_DT_RTOL) -> list[Finding]:
    """Findings for one record, in time order (detectors and rules in the module docstring)."""
    out = _slow_clock(record) + _sampling(record, dt_rtol)
    constant = [
        (c, x) for c, x in ((record.input_name, record.u), (record.output_name, record.y)) if x is not None and np.ptp(x) == 0
    ]
    for c, x in constant:
        out.append(
            _finding(
                record,
                "constant",
                c,
                0,
                len(record),
                math.nan,
                math.nan,
                f"'{c}' is {float(x[0]):.6g} throughout: nothing to identify from this record",
                "drop",
            )
        )
    if constant:
        return out
    u = np.asarray(record.u, float)
    # a drive voltage is commanded: it may hold any level for any time (a pulse, the top step of a staircase), so
    # only a measured input (temperature, pressure, ...) is searched for glitch blocks
    glitches = [] if is_voltage(record.input_name, record.units) else _glitches(record, u, record.input_name, dt_rtol)
    out += glitches + _inside_none(_spikes(record, u, record.input_name, drive=True), glitches)
    if record.y is not None:
        y = np.asarray(record.y, float)
        spikes = _spikes(record, y, record.output_name)
        # steps are looked for after the spikes are bridged: a spike inside a median window biases it
        y_clean = y.copy()
        for f in spikes:
            a, b = f.index
            y_clean[a:b] = np.interp(np.arange(a, b), [a - 1, b], [y[a - 1], y[b]])
        jumps = _jumps(record, dt_rtol, y_clean)
        # an offset stretch entered and left while the input holds is the offset_jump's (with its remedy, subtract)
        blocks = [
            g
            for g in _glitches(record, y, record.output_name, dt_rtol, other=u)
            if not any(j.index[0] < g.index[1] and g.index[0] < j.index[1] for j in jumps)
        ]
        out += blocks + _inside_none(spikes, blocks) + jumps + _flats(record)
    return sorted(out, key=lambda f: (f.index[0], f.kind))


# -- across records ---------------------------------------------------------------------


def _levels(recs: list[Record]) -> list[Finding]:
    recs = [r for r in recs if r.y is not None]
    if len(recs) < 2:
        return []
    lo = max(float(np.percentile(r.u, 1)) for r in recs)
    hi = min(float(np.percentile(r.u, 99)) for r in recs)
    if not hi > lo:
        return []
    edges = np.linspace(lo, hi, LEVEL_BINS + 1)
    m = np.full((len(recs), LEVEL_BINS), np.nan)
    for i, r in enumerate(recs):
        b = np.digitize(r.u, edges[1:-1])
        inside = (r.u >= lo) & (r.u <= hi)
        for j in range(LEVEL_BINS):
            sel = inside & (b == j)
            if sel.sum() >= 3:
                m[i, j] = np.median(r.y[sel])
    ref = np.array([np.median(c[np.isfinite(c)]) if np.isfinite(c).any() else np.nan for c in m.T])
    scale = float(np.nanmedian([robust_range(r.y) for r in recs]))
    out = []
    for i, r in enumerate(recs):
        diff = m[i] - ref
        others = np.sum(np.isfinite(m), axis=0) >= 2
        diff = diff[np.isfinite(diff) & others]
        if diff.size == 0 or not math.isfinite(scale):
            continue
        if (np.all(diff > 0) or np.all(diff < 0)) and float(np.min(np.abs(diff))) >= LEVEL_REL * scale:
            size = float(np.median(diff))
            note = " (with two records the odd one cannot be told)" if len(recs) == 2 else ""
            out.append(
                _finding(
                    r,
                    "level_mismatch",
                    r.output_name,
                    0,
                    len(r),
                    size,
                    scale,
                    f"whole run shifted by {size:+.4g} against the other records at every shared input level "
                    f"({diff.size} bins){note}; drop it or subtract the offset",
                    "drop",
                )
            )
    return out


def _input_ranges(recs: list[Record]) -> list[Finding]:
    if len(recs) < 2:
        return []
    pct = [np.percentile(r.u, [0.5, 99.5]) for r in recs]
    out = []
    for i, r in enumerate(recs):
        others = [p for j, p in enumerate(pct) if j != i]
        # the band that at least RANGE_COVER of the others reach (with three or more others): a faulty record's range
        # alone (a glitch to 220 C) does not count as trained, so two faulty records do not hide each other
        k = RANGE_COVER if len(others) > RANGE_COVER else 1
        lo, hi = sorted(p[0] for p in others)[k - 1], sorted(p[1] for p in others)[-k]
        lo, hi = lo - RANGE_TOL * (hi - lo), hi + RANGE_TOL * (hi - lo)  # holds at the very end of the range are inside
        outside = float(np.mean((r.u < lo) | (r.u > hi)))
        span = float(pct[i][1] - pct[i][0])
        ref = float(np.median([p[1] - p[0] for p in others]))
        if outside > RANGE_OUT:
            out.append(
                _finding(
                    r,
                    "input_range",
                    r.input_name,
                    0,
                    len(r),
                    math.nan,
                    math.nan,
                    f"{100 * outside:.0f} % of the input lies outside the other records' range [{lo:.4g}, {hi:.4g}]"
                    + (f" (reached by at least {k} of them)" if k > 1 else "")
                    + ": a model "
                    "trained on them extrapolates here (keep it in training, not as a held-out record)",
                    "check",
                )
            )
        elif ref > 0 and span < RANGE_SPAN * ref:
            out.append(
                _finding(
                    r,
                    "input_range",
                    r.input_name,
                    0,
                    len(r),
                    span,
                    span / ref,
                    f"input span {span:.4g} is {100 * span / ref:.0f} % of the other records' median span {ref:.4g}",
                    "check",
                )
            )
    return out


def _dt_groups(dts: list[float], dt_rtol: float) -> list[list[int]]:
    """Record indices grouped by sample time: sorted, a new group when a time is off its group's first by > ``dt_rtol``."""
    groups: list[list[int]] = []
    for i in np.argsort(dts, kind="stable"):
        if groups and abs(dts[i] - dts[groups[-1][0]]) <= dt_rtol * dts[groups[-1][0]]:
            groups[-1].append(int(i))
        else:
            groups.append([int(i)])
    return groups


def _sample_times(recs: list[Record], dt_rtol: float) -> list[Finding]:
    out = []
    dts = [float(r.dt) for r in recs]
    groups = _dt_groups(dts, dt_rtol)
    if len(groups) > 1:
        most = max(groups, key=len)
        if 2 * len(most) > len(recs):
            # the group's middle sample time, one a record has (the median of an even count would be none of them)
            ref = sorted(dts[i] for i in most)[(len(most) - 1) // 2]
            for i, r in enumerate(recs):
                if i not in most:
                    out.append(
                        _finding(
                            r,
                            "dt_mismatch",
                            "time_s",
                            0,
                            len(r),
                            r.dt - ref,
                            math.nan,
                            f"sample time {r.dt:.6g} s vs {ref:.6g} s in {len(most)} of the {len(recs)} records; resample to "
                            f"{ref:.6g} s if the model needs one grid",
                            "resample",
                        )
                    )
        else:
            listed = ", ".join(f"{r.name} {r.dt:.6g} s" for r in recs[:8]) + (
                f" and {len(recs) - 8} more" if len(recs) > 8 else ""
            )
            for r in recs:
                out.append(
                    _finding(
                        r,
                        "dt_mismatch",
                        "time_s",
                        0,
                        len(r),
                        math.nan,
                        math.nan,
                        f"sample time {r.dt:.6g} s: the records have different sample times and no one is shared by most "
                        f"({listed}); if the model needs one grid, resample them to one of these (--resample DT)",
                        "resample",
                    )
                )
    seen = {}
    for r in recs:
        key = r.sha256 or None
        if key is None:
            continue
        if key in seen:
            out.append(
                _finding(
                    r, "duplicate", "*", 0, len(r), math.nan, math.nan, f"same content as {seen[key]}; drop one copy", "drop"
                )
            )
        else:
            seen[key] = r.name
    return out


def check_records(records: list[Record], *, per_record: bool = True, dt_rtol: float = DEFAULT_DT_RTOL) -> list[Finding]:
    """Findings for a set of records: each record's own (``per_record``) then the comparisons across the set."""
    records = list(records)
    out = []
    if per_record:
        for r in records:
            out += check_record(r, dt_rtol=dt_rtol)
    if len(records) >= 2:
        out += _sample_times(records, dt_rtol)
        out += _levels(records)
        out += _input_ranges(records)
    return out
