"""Loading measured records from CSV (+ optional JSON sidecar) with precise errors.

A record file is a CSV with a header row: a time column (``time_s``), an input
column and an output column; other columns are allowed and kept in
``Record.extra`` when numeric (ambient temperature, load, branch labels...).
A sidecar ``NAME.json`` beside ``NAME.csv`` may give ``units`` (column ->
unit), ``description``, and default ``input`` / ``output`` column names.

Every problem raises `DataError` naming the file, the column and the line
(line 1 is the header), so the CLI can print it without a traceback.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import math
from pathlib import Path

import numpy as np

from ._errors import DataError

__all__ = ["Record", "load_record", "file_sha256", "INPUT_CANDIDATES", "OUTPUT_CANDIDATES"]

INPUT_CANDIDATES = ("voltage_V", "voltage", "input", "u")
OUTPUT_CANDIDATES = ("displacement_mm", "displacement", "output", "y", "length_signal")

#: Relative tolerance on the spread of sample intervals before a record is called irregular.
#: Logged time stamps are often rounded (1 ms stamps on a 10 ms clock jitter by 10 %), so
#: jitter is accepted; gaps (a missing stretch, a paused logger) are not.
DEFAULT_DT_RTOL = 0.15


@dataclasses.dataclass(frozen=True)
class Record:
    """One measured (or synthetic) record on a regular time grid."""

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

    def __len__(self):
        return int(self.time.shape[0])

    @property
    def name(self):
        return Path(self.path).stem if self.path else "record"

    def take(self, index):
        """Sub-record at integer indices or a boolean mask (keeps ``dt``; used for splits)."""
        index = np.asarray(index)
        return dataclasses.replace(
            self,
            time=self.time[index],
            u=self.u[index],
            y=None if self.y is None else self.y[index],
            extra={k: v[index] for k, v in self.extra.items()},
        )

    @classmethod
    def from_arrays(cls, time, u, y=None, *, input_name="input", output_name="output", extra=None, units=None):
        """Record from in-memory arrays (validated like a file)."""
        time = np.asarray(time, dtype=np.float64)
        u = np.asarray(u, dtype=np.float64)
        cols = {"time_s": time, input_name: u}
        if y is not None:
            cols[output_name] = np.asarray(y, dtype=np.float64)
        for k, v in (extra or {}).items():
            cols[k] = np.asarray(v, dtype=np.float64)
        lengths = {k: np.shape(v) for k, v in cols.items()}
        if len({s for s in lengths.values()}) != 1 or time.ndim != 1:
            raise DataError("<arrays>", f"all columns must be 1-D of one length, got shapes {lengths}")
        for k, v in cols.items():
            if not np.all(np.isfinite(v)) and k in ("time_s", input_name, output_name):
                bad = int(np.flatnonzero(~np.isfinite(v))[0])
                raise DataError("<arrays>", "non-finite value", column=k, row=bad)
        dt = _check_time("<arrays>", "time_s", time, DEFAULT_DT_RTOL, line_offset=0)
        return cls(
            time=time,
            u=u,
            y=cols.get(output_name) if y is not None else None,
            dt=dt,
            input_name=input_name,
            output_name=output_name if y is not None else None,
            extra={k: v for k, v in cols.items() if k not in ("time_s", input_name, output_name)},
            units=dict(units or {}),
        )


def file_sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _read_sidecar(path):
    side = path.with_suffix(".json")
    if not side.exists():
        return {}
    try:
        meta = json.loads(side.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DataError(side, f"sidecar is not valid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise DataError(side, "sidecar must hold a JSON object")
    units = meta.get("units", {})
    if not isinstance(units, dict):
        raise DataError(side, "'units' must be an object mapping column -> unit")
    return meta


def _pick(path, header, wanted, candidates, role, option):
    if wanted is not None:
        if wanted not in header:
            raise DataError(path, f"no {role} column '{wanted}'; columns are {header}", column=wanted)
        return wanted
    found = [c for c in candidates if c in header]
    if not found:
        raise DataError(path, f"cannot tell which column is the {role}; choose one of {header} with {option} COLUMN")
    return found[0]


def _check_time(path, col, t, rtol, line_offset=2):
    d = np.diff(t)
    bad = np.flatnonzero(d == 0)
    if bad.size:
        raise DataError(path, f"duplicated time value {float(t[bad[0] + 1]):g}", column=col, row=int(bad[0] + 1 + line_offset))
    bad = np.flatnonzero(d < 0)
    if bad.size:
        raise DataError(
            path,
            f"time goes backwards ({float(t[bad[0]]):g} -> {float(t[bad[0] + 1]):g})",
            column=col,
            row=int(bad[0] + 1 + line_offset),
        )
    dt = float(np.median(d))
    bad = np.flatnonzero(np.abs(d - dt) > rtol * dt)
    if bad.size:
        k = int(bad[0])
        raise DataError(
            path,
            f"irregular sampling: step {float(d[k]):.6g} s vs median {dt:.6g} s (tolerance {rtol:.0%}); resample the record or cut it at the gap",
            column=col,
            row=k + 1 + line_offset,
        )
    return dt


def load_record(
    path,
    input=None,
    output=None,
    *,
    time="time_s",
    require_output=True,
    min_samples=10,
    dt_rtol=DEFAULT_DT_RTOL,
):
    """Read and validate a record; ``input``/``output`` select columns (defaults: sidecar, then common names).

    ``row`` numbers in errors are file line numbers (the header is line 1).
    """
    path = Path(path)
    if not path.exists():
        raise DataError(path, "file not found")
    if path.is_dir():
        raise DataError(path, "is a directory, expected a CSV file")
    meta = _read_sidecar(path)
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except UnicodeDecodeError:
        raise DataError(path, "not a text CSV file") from None
    rows = [r for r in rows if any(c.strip() for c in r)]
    if not rows:
        raise DataError(path, "file is empty")
    header = [h.strip() for h in rows[0]]
    if len(set(header)) != len(header):
        raise DataError(path, f"duplicated column names in header {header}", row=1)
    body = rows[1:]
    if not body:
        raise DataError(path, "header only, no data rows")
    if time not in header:
        raise DataError(path, f"no time column '{time}'; columns are {header}", column=time)
    in_col = _pick(path, header, input if input is not None else meta.get("input"), INPUT_CANDIDATES, "input", "--input")
    out_col = None
    if require_output or output is not None:
        out_col = _pick(
            path, header, output if output is not None else meta.get("output"), OUTPUT_CANDIDATES, "output", "--output"
        )
        if out_col == in_col:
            raise DataError(path, f"input and output are the same column '{in_col}'")
    required = [time, in_col] + ([out_col] if out_col else [])
    idx = {h: i for i, h in enumerate(header)}
    cols = {h: np.empty(len(body)) for h in header}
    numeric = {h: True for h in header}
    for j, row in enumerate(body):
        line = j + 2
        if len(row) != len(header):
            raise DataError(path, f"expected {len(header)} cells, found {len(row)}", row=line)
        for h in header:
            cell = row[idx[h]].strip()
            try:
                val = float(cell)
            except ValueError:
                if h in required:
                    raise DataError(path, f"non-numeric value {cell!r}", column=h, row=line) from None
                numeric[h] = False
                continue
            if h in required and not math.isfinite(val):
                raise DataError(path, f"non-finite value {cell!r}", column=h, row=line)
            cols[h][j] = val
    if len(body) < min_samples:
        raise DataError(path, f"too few samples: {len(body)} rows, need at least {min_samples}")
    dt = _check_time(path, time, cols[time], dt_rtol)
    extra = {h: cols[h] for h in header if h not in required and numeric[h]}
    return Record(
        time=cols[time],
        u=cols[in_col],
        y=cols[out_col] if out_col else None,
        dt=dt,
        input_name=in_col,
        output_name=out_col,
        extra=extra,
        units=dict(meta.get("units", {})),
        description=str(meta.get("description", "")),
        path=str(path),
        sha256=file_sha256(path),
    )
