"""`Record`: one measured (or synthetic) record: time, input, output and the story of how it was read.

A record is normally on a uniform time grid (``dt``); `load_record` refuses
irregular time stamps unless asked to resample them (then ``processing`` says
how, and ``gaps`` lists every interval that was bridged by interpolation).
Only `smafl check` keeps irregular stamps as they are, to report them.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from smafl_jax._errors import DataError

__all__ = ["Record", "DEFAULT_DT_RTOL", "check_time"]

#: Relative tolerance on the spread of sample intervals before a record is called irregular.
#: Logged time stamps are often rounded (1 ms stamps on a 10 ms clock jitter by 10 %), so
#: jitter is accepted; gaps (a missing stretch, a paused logger) are not.
DEFAULT_DT_RTOL = 0.15


#: A grid point within this fraction of a sample time of a bridged gap's end stamp is that stamp (a time column written
#: with fewer digits than the grid's float arithmetic: 0.7 read vs 7 x 0.1 = 0.7000000000000001 on the grid).
STAMP_RTOL = 1e-6

#: A step of at least this many sample times misses a sample: a gap (what `--resample` bridges, what the noise estimate
#: on the stamps as read and the ``gap_input`` check leave out or look at); a jittered step of 1.3 misses none.
GAP_STEPS = 1.5


def interpolated_mask(time, gaps, dt: float) -> np.ndarray:
    """True on the samples of ``time`` strictly inside one of the ``gaps`` ``(t_start, t_end)`` (more than
    `STAMP_RTOL` x ``dt`` from both ends): the grid points a resampling filled in by linear interpolation."""
    t = np.asarray(time, dtype=np.float64)  # increasing, as every record's time axis
    if not len(gaps):
        return np.zeros(t.shape[0], bool)
    tol = STAMP_RTOL * float(dt)
    ends = np.asarray(gaps, dtype=np.float64).reshape(-1, 2)
    # one pass over the samples however many gaps (a long burst-logged record has tens of thousands)
    lo = np.searchsorted(t, ends[:, 0] + tol, side="right")
    hi = np.searchsorted(t, ends[:, 1] - tol, side="left")
    marks = np.zeros(t.shape[0] + 1, int)
    np.add.at(marks, lo, 1)
    np.add.at(marks, np.maximum(hi, lo), -1)
    return np.cumsum(marks)[:-1] > 0


@dataclasses.dataclass(frozen=True, eq=False)
class Record:
    """One record: ``time`` (s), input ``u``, output ``y`` (or None), sample time ``dt`` and provenance.

    ``extra``: other numeric columns (ambient temperature, load, branch labels...).
    ``processing``: what was done to the data on loading, one sentence per step
    (empty when the file was used exactly as written).  ``gaps``: ``(t_start, t_end)``
    of every original sampling interval longer than the tolerance that resampling
    bridged.  ``load``: a per-record load from the sidecar (``"load": 200``; its
    unit in ``units["load"]``).  ``metadata``: the whole sidecar object.
    ``time_name``: the file's time column (``time`` holds it in seconds whatever its unit in the file).
    ``as_read``: for a resampled record, the record on its time stamps as read (irregular, not for fitting); None
    otherwise.  Kept for what interpolation destroys: the output noise (`smafl_jax.noise_floor` estimates it there:
    interpolating between jittered stamps averages neighbouring samples, and read 1.7x low) and the input between
    gaps (`smafl_jax.data.check_record`).
    """

    time: np.ndarray
    u: np.ndarray
    y: np.ndarray | None
    dt: float
    input_name: str
    output_name: str | None
    extra: dict = dataclasses.field(default_factory=dict)
    units: dict = dataclasses.field(default_factory=dict)
    description: str = ""
    path: str | None = None
    sha256: str | None = None
    processing: tuple[str, ...] = ()
    gaps: tuple[tuple[float, float], ...] = ()
    load: float | None = None
    metadata: dict = dataclasses.field(default_factory=dict)
    record_name: str = ""
    time_name: str = "time_s"
    as_read: Record | None = None

    def __len__(self) -> int:
        return int(self.time.shape[0])

    @property
    def name(self) -> str:
        """``record_name`` if given, else the file stem, else ``"record"``."""
        if self.record_name:
            return self.record_name
        return Path(self.path).stem if self.path else "record"

    @property
    def measured(self) -> np.ndarray:
        """Boolean mask of the samples that were measured: False on the grid points inside a gap that resampling
        bridged (``gaps``), which a straight line filled in (`interpolated_mask`).  Fits give them no weight and scores
        leave them out (a record resampled from logger bursts had 26 % of them); the model still runs through them.
        All True for a record read as written."""
        return ~interpolated_mask(self.time, self.gaps, self.dt)

    def take(self, index) -> Record:
        """Sub-record at integer indices or a boolean mask (keeps ``dt``; used for splits)."""
        index = np.asarray(index)
        return dataclasses.replace(
            self,
            time=self.time[index],
            u=self.u[index],
            y=None if self.y is None else self.y[index],
            extra={k: v[index] for k, v in self.extra.items()},
        )

    def window(self, start: float | None = None, end: float | None = None, *, min_samples: int = 10) -> Record:
        """The samples with ``start <= time <= end`` (seconds on the record's own time axis; None = open), said in
        ``processing``: how a user acts on a data-check finding ("cut the samples before 8.07 s") without editing
        the file.  `DataError` when the window keeps fewer than ``min_samples`` samples."""
        where = self.path or f"<arrays {self.name}>"
        t0 = -np.inf if start is None else float(start)
        t1 = np.inf if end is None else float(end)
        if not t0 < t1:
            raise DataError(where, f"the window [{t0:g}, {t1:g}] s is empty: its start must be before its end")
        keep = (self.time >= t0) & (self.time <= t1)
        n = int(keep.sum())
        span = f"[{self.time[0]:.6g}, {self.time[-1]:.6g}] s"
        if n < min_samples:
            raise DataError(
                where,
                f"the window [{t0:g}, {t1:g}] s keeps {n} of {len(self)} samples (the record spans {span}); need at least {min_samples}",
            )
        if n == len(self):
            return self
        cut = self.take(keep)
        kept = f"[{cut.time[0]:.6g}, {cut.time[-1]:.6g}] s"
        note = f"kept the window {kept} of {span} ({n} of {len(self)} samples)"
        gaps = tuple(g for g in self.gaps if g[1] >= cut.time[0] and g[0] <= cut.time[-1])
        return dataclasses.replace(cut, processing=(*self.processing, note), gaps=gaps)

    @classmethod
    def from_arrays(
        cls,
        time,
        u,
        y=None,
        *,
        input_name: str = "input",
        output_name: str = "output",
        extra: dict | None = None,
        units: dict | None = None,
        name: str = "",
        load: float | None = None,
        description: str = "",
        dt_rtol: float = DEFAULT_DT_RTOL,
    ) -> Record:
        """Record from in-memory arrays (validated like a file: finite, 1-D, one length, uniform time)."""
        where = f"<arrays {name}>" if name else "<arrays>"
        time = np.asarray(time, dtype=np.float64)
        u = np.asarray(u, dtype=np.float64)
        cols = {"time_s": time, input_name: u}
        if y is not None:
            if output_name in cols:
                raise DataError(where, f"output name {output_name!r} clashes with the time or input column")
            cols[output_name] = np.asarray(y, dtype=np.float64)
        for k, v in (extra or {}).items():
            if k in cols:
                raise DataError(where, f"extra column {k!r} clashes with another column")
            cols[k] = np.asarray(v, dtype=np.float64)
        shapes = {k: np.shape(v) for k, v in cols.items()}
        if len(set(shapes.values())) != 1 or time.ndim != 1:
            raise DataError(where, f"all columns must be 1-D of one length, got shapes {shapes}")
        for k in ("time_s", input_name, output_name):
            if k in cols and not np.all(np.isfinite(cols[k])):
                bad = int(np.flatnonzero(~np.isfinite(cols[k]))[0])
                raise DataError(where, "non-finite value", column=k, row=bad)
        if time.size < 2:
            raise DataError(where, f"need at least 2 samples, got {time.size}")
        dt = check_time(where, "time_s", time, dt_rtol, line_of=lambda i: i)
        return cls(
            time=time,
            u=u,
            y=cols.get(output_name) if y is not None else None,
            dt=dt,
            input_name=input_name,
            output_name=output_name if y is not None else None,
            extra={k: v for k, v in cols.items() if k not in ("time_s", input_name, output_name)},
            units=dict(units or {}),
            description=description,
            load=None if load is None else float(load),
            record_name=name,
        )


def check_time(path, col: str, t: np.ndarray, rtol: float | None, line_of=lambda i: i + 2) -> float:
    """Median sample time of strictly increasing stamps ``t``; `DataError` on duplicates, reversals and (``rtol``) gaps.

    ``line_of(i)`` maps a sample index to the row number shown in messages (file
    line numbers for files, sample indices for arrays).  ``rtol=None`` skips the
    regularity test (used when the caller resamples or keeps irregular stamps).
    """
    d = np.diff(t)
    bad = np.flatnonzero(d == 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise DataError(path, f"duplicated time value {float(t[k]):g} ({bad.size} duplicates in all)", column=col, row=line_of(k))
    bad = np.flatnonzero(d < 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise DataError(path, f"time goes backwards ({float(t[k - 1]):g} -> {float(t[k]):g})", column=col, row=line_of(k))
    dt = float(np.median(d))
    if rtol is None:
        return dt
    bad = np.flatnonzero(np.abs(d - dt) > rtol * dt)
    if bad.size:
        k = int(bad[0])
        longest = int(bad[np.argmax(d[bad])])
        raise DataError(
            path,
            f"irregular sampling: step {float(d[k]):.6g} s vs median {dt:.6g} s (tolerance {rtol:.0%}) at t = {float(t[k]):.6g} s; "
            f"{bad.size} irregular steps in all, the longest {float(d[longest]):.6g} s at t = {float(t[longest]):.6g} s. "
            f"Fix: resample onto a uniform grid (CLI: --resample {dt:.6g}; Python: resample={dt:.6g}), which interpolates "
            "linearly and reports every bridged gap, or cut the record at the gap",
            column=col,
            row=line_of(k + 1),
        )
    return dt
