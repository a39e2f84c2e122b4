"""Reading records from CSV files (+ optional JSON sidecar) with precise errors.

A record file is a CSV with a header row: a time column (``time_s``), an input
column and an output column; other numeric columns are kept in ``Record.extra``
(ambient temperature, load, branch labels...).  A sidecar ``NAME.json`` beside
``NAME.csv`` may give ``units`` (column -> unit), ``description``, default
``input`` / ``output`` column names and a per-record ``load`` (a number).

Reading rules (each documented, nothing changed silently):

- Encoding: UTF-8, a byte-order mark (Excel) is stripped; files that are not
  UTF-8 are read as cp1252 (Windows Excel) and ``Record.processing`` says so;
  a file with NUL bytes is refused as binary (an ``.xlsx``?).
- Delimiter: the one of ``,`` ``;`` TAB that occurs most often in the header
  line.  With ``;`` or TAB, a decimal comma in the cells (``1,5``) is read as a
  decimal point (European Excel exports).
- A cell over the CSV field limit (131 072 characters: an unclosed quote, a
  pasted blob) raises `DataError` with the line, not ``_csv.Error``.
- Non-numeric or empty cells in the time, input or output column raise
  `DataError` naming line and column; NaN/inf there likewise (all offending
  lines listed, up to 5).  Other columns that are not numeric are left out of
  ``extra`` and ``processing`` says so.
- Time stamps must increase strictly (duplicates and reversals name the line).
- Irregular sampling (a step off the median step by more than ``dt_rtol``) is
  refused with the gap and the fix, unless ``resample=DT`` is given: the record
  is then interpolated linearly onto ``t0 + k DT`` (integer-valued extra columns
  such as branch labels are held, not interpolated).  Across a gap the linear
  interpolation *bridges* the gap (a straight line between the last sample
  before and the first after); every bridged interval is kept in
  ``Record.gaps`` and summarised in ``Record.processing``, and `check_record`
  reports long gaps so they can be cut or left out of scoring.  Bridging
  rather than splitting keeps one record per file (models carry state through
  the gap); at the cavatappi logger's 20-30 ms gaps between 10-sample bursts
  the bridge spans two or three samples.
"""

from __future__ import annotations

import csv
import dataclasses
import glob as _glob
import hashlib
import json
import math
import os
from pathlib import Path

import numpy as np

from smafl_jax._errors import DataError, UserInputError

from .record import DEFAULT_DT_RTOL, Record, check_time

__all__ = ["load_record", "load_records", "file_sha256", "resample_record", "INPUT_CANDIDATES", "OUTPUT_CANDIDATES"]

#: Column names taken as the input / output without --input / --output, first match wins (a drive voltage before a
#: directly measured input, so a file that also logs a temperature is still fitted from its voltage).
INPUT_CANDIDATES = ("voltage_V", "voltage", "input", "u", "temperature_C", "temperature", "pressure")
OUTPUT_CANDIDATES = ("displacement_mm", "displacement", "output", "y", "length_signal", "length_mm", "length")
DELIMITERS = (",", ";", "\t")
_DELIM_NAMES = {",": "comma", ";": "semicolon", "\t": "tab"}
#: Gaps at least this many sample times long are listed one by one in ``processing``.
LONG_GAP_STEPS = 10


def file_sha256(path: str | os.PathLike) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _read_sidecar(path: Path) -> dict:
    side = path.with_suffix(".json")
    if not side.exists():
        return {}
    try:
        meta = json.loads(side.read_text(encoding="utf-8-sig"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DataError(side, f"sidecar is not valid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise DataError(side, "sidecar must hold a JSON object")
    if not isinstance(meta.get("units", {}), dict):
        raise DataError(side, "'units' must be an object mapping column -> unit")
    load = meta.get("load")
    if load is not None and (isinstance(load, bool) or not isinstance(load, (int, float)) or not math.isfinite(load)):
        raise DataError(side, f"'load' must be a finite number (its unit in units['load']), got {load!r}")
    return meta


def _decode(path: Path, raw: bytes) -> tuple[str, list[str]]:
    notes = []
    if b"\x00" in raw[:65536]:
        raise DataError(path, "binary file (NUL bytes), not a text CSV; export it from the spreadsheet as CSV")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        try:
            text = raw.decode("cp1252")
        except UnicodeDecodeError:
            raise DataError(path, f"not a text CSV file (undecodable byte at offset {exc.start})") from None
        notes.append("decoded as cp1252 (Windows) text: the file is not UTF-8")
    if text.startswith("\ufeff"):
        text = text[1:]
        notes.append("UTF-8 byte-order mark stripped")
    return text, notes


def _sniff_delimiter(path: Path, header_line: str) -> str:
    counts = {d: header_line.count(d) for d in DELIMITERS}
    best = max(DELIMITERS, key=lambda d: counts[d])
    if counts[best] == 0:
        raise DataError(path, f"cannot find a delimiter (comma, semicolon or tab) in the header line {header_line[:80]!r}", row=1)
    return best


def _parse_rows(path: Path, text: str, delim: str) -> tuple[list[list[str]], list[int]]:
    """Non-blank rows and the file line each starts on."""
    rows, lines = [], []
    reader = csv.reader(text.splitlines(), delimiter=delim)
    while True:
        start = reader.line_num + 1
        try:
            row = next(reader)
        except StopIteration:
            break
        except csv.Error as exc:
            raise DataError(
                path,
                f"cannot parse the CSV ({exc}): a cell over the {csv.field_size_limit()}-character limit or an unclosed quote "
                "starting here",
                row=start,
            ) from None
        if any(c.strip() for c in row):
            rows.append(row)
            lines.append(start)
    return rows, lines


def _to_float(cells: list[str], decimal_comma: bool) -> np.ndarray | None:
    """Fast column conversion; None when some cell is not a number (the caller finds which)."""
    if decimal_comma:
        cells = [c.replace(",", ".") for c in cells]
    try:
        return np.array([c.strip() for c in cells], dtype=np.float64) if cells else np.empty(0)
    except ValueError:
        return None


def _first_bad_cell(cells: list[str], decimal_comma: bool) -> int:
    for j, c in enumerate(cells):
        try:
            float(c.replace(",", ".") if decimal_comma else c)
        except ValueError:
            return j
    return -1


def _pick(path, header, wanted, candidates, role, option):
    if wanted is not None:
        if wanted not in header:
            raise DataError(path, f"no {role} column '{wanted}'; columns are {header}", column=wanted)
        return wanted
    found = [c for c in candidates if c in header]
    if not found:
        raise DataError(path, f"cannot tell which column is the {role}; choose one of {header} with {option} COLUMN")
    return found[0]


def _lines_text(lines) -> str:
    lines = [int(x) for x in lines]
    more = f" and {len(lines) - 5} more" if len(lines) > 5 else ""
    return ", ".join(str(x) for x in lines[:5]) + more


def load_record(
    path: str | os.PathLike,
    input: str | None = None,
    output: str | None = None,
    *,
    time: str = "time_s",
    require_output: bool = True,
    min_samples: int = 10,
    dt_rtol: float = DEFAULT_DT_RTOL,
    resample: float | str | None = None,
    irregular: str = "error",
) -> Record:
    """Read and validate one record (rules in the module docstring).

    ``input``/``output`` select columns (defaults: the sidecar's, then common
    names).  ``resample``: a sample time in seconds, or ``"auto"`` (the median
    step), to put irregular stamps on a uniform grid.  ``irregular="keep"``
    keeps irregular stamps as they are (``dt`` = median step) for `check_record`
    to report; models need a uniform grid, so fitting code leaves it at
    ``"error"``.  ``row`` numbers in errors are file line numbers (header = 1).
    """
    path = Path(path)
    if irregular not in ("error", "keep"):
        raise UserInputError(f"irregular must be 'error' or 'keep', got {irregular!r}")
    if not path.exists():
        raise DataError(path, "file not found")
    if path.is_dir():
        raise DataError(path, "is a directory, expected a CSV file")
    meta = _read_sidecar(path)
    raw = path.read_bytes()
    text, notes = _decode(path, raw)
    first = next((ln for ln in text.splitlines() if ln.strip()), None)
    if first is None:
        raise DataError(path, "file is empty")
    delim = _sniff_delimiter(path, first)
    decimal_comma = delim != ","
    rows, lines = _parse_rows(path, text, delim)
    header = [h.strip() for h in rows[0]]
    body, lines = rows[1:], lines[1:]
    # a trailing delimiter on every line (some exports) gives an unnamed, empty last column
    if header and header[-1] == "" and all(len(r) == len(header) and not r[-1].strip() for r in body):
        header, body = header[:-1], [r[:-1] for r in body]
        notes.append("empty unnamed last column (trailing delimiters) ignored")
    if "" in header:
        raise DataError(path, f"empty column name at position {header.index('') + 1} of the header {header}", row=1)
    if len(set(header)) != len(header):
        raise DataError(path, f"duplicated column names in header {header}", row=1)
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
    if in_col == time or out_col == time:
        raise DataError(path, f"the time column '{time}' cannot also be the input or output")
    for row, line in zip(body, lines):
        if len(row) != len(header):
            raise DataError(path, f"expected {len(header)} cells, found {len(row)}", row=line)
    required = [time, in_col] + ([out_col] if out_col else [])
    cols: dict[str, np.ndarray] = {}
    for i, h in enumerate(header):
        cells = [r[i] for r in body]
        x = _to_float(cells, decimal_comma)
        if x is None:
            j = _first_bad_cell(cells, decimal_comma)
            if h in required:
                what = "empty cell" if not cells[j].strip() else f"non-numeric value {cells[j].strip()[:40]!r}"
                raise DataError(path, what, column=h, row=lines[j])
            notes.append(f"column '{h}' is not numeric (line {lines[j]}: {cells[j].strip()[:20]!r}): left out")
            continue
        if h in required and not np.all(np.isfinite(x)):
            bad = np.flatnonzero(~np.isfinite(x))
            raise DataError(
                path,
                f"non-finite value {cells[bad[0]].strip()!r} (lines {_lines_text(np.asarray(lines)[bad])})",
                column=h,
                row=lines[bad[0]],
            )
        cols[h] = x
    if decimal_comma and any("," in r[header.index(h)] for r in body[:50] for h in cols):
        notes.append(f"{_DELIM_NAMES[delim]}-delimited with decimal commas: read as decimal points")
    if len(body) < min_samples:
        raise DataError(path, f"too few samples: {len(body)} rows, need at least {min_samples}")
    t = cols[time]
    line_of = lambda k: lines[k]
    if resample is None:
        dt = check_time(path, time, t, None if irregular == "keep" else dt_rtol, line_of=line_of)
        if irregular == "keep":
            d = np.diff(t)
            n_bad = int(np.sum(np.abs(d - dt) > dt_rtol * dt))
            if n_bad:
                notes.append(f"irregular time stamps kept as they are ({n_bad} steps off the median {dt:.6g} s); not for fitting")
    else:
        check_time(path, time, t, None, line_of=line_of)
    rec = Record(
        time=t,
        u=cols[in_col],
        y=cols[out_col] if out_col else None,
        dt=dt if resample is None else float(np.median(np.diff(t))),
        input_name=in_col,
        output_name=out_col,
        extra={h: v for h, v in cols.items() if h not in required},
        units=dict(meta.get("units", {})),
        description=str(meta.get("description", "")),
        path=str(path),
        sha256=hashlib.sha256(raw).hexdigest(),
        processing=tuple(notes),
        load=None if meta.get("load") is None else float(meta["load"]),
        metadata=meta,
    )
    if resample is not None:
        rec = resample_record(rec, resample, dt_rtol=dt_rtol, min_samples=min_samples)
    return rec


def resample_record(rec: Record, dt: float | str = "auto", *, dt_rtol: float = DEFAULT_DT_RTOL, min_samples: int = 2) -> Record:
    """``rec`` on the uniform grid ``t0 + k dt`` by linear interpolation; gaps bridged and reported (module docstring).

    A record already uniform at ``dt`` (within ``dt_rtol``) is returned with a
    note and its samples untouched.
    """
    t = np.asarray(rec.time, float)
    d = np.diff(t)
    med = float(np.median(d))
    where = rec.path or rec.name
    if isinstance(dt, str):
        if dt != "auto":
            raise UserInputError(f"resample must be a sample time in seconds or 'auto', got {dt!r}")
        dt = med
    dt = float(dt)
    span = float(t[-1] - t[0])
    if not (math.isfinite(dt) and dt > 0):
        raise UserInputError(f"resample step must be a positive number of seconds, got {dt!r}")
    if span / dt + 1 < min_samples:
        raise UserInputError(
            f"{where}: resample step {dt:g} s leaves fewer than {min_samples} samples over the {span:g} s record"
        )
    irregular = np.abs(d - med) > dt_rtol * med
    if not irregular.any() and abs(med - dt) <= dt_rtol * dt:
        note = f"resampling to {dt:g} s requested: the record is already uniform at {med:.6g} s, samples kept as read"
        return dataclasses.replace(rec, dt=med, processing=(*rec.processing, note))
    grid = t[0] + dt * np.arange(math.floor(span / dt * (1 + 1e-12)) + 1)
    gap_idx = np.flatnonzero(d > (1 + dt_rtol) * dt)
    gaps = tuple((float(t[k]), float(t[k + 1])) for k in gap_idx)
    in_gap = np.zeros(grid.size, bool)
    if gap_idx.size:
        # grid points strictly inside a bridged interval are interpolated across missing data
        lo = np.searchsorted(grid, t[gap_idx], side="right")
        hi = np.searchsorted(grid, t[gap_idx + 1], side="left")
        marks = np.zeros(grid.size + 1, int)
        np.add.at(marks, lo, 1)
        np.add.at(marks, hi, -1)
        in_gap = np.cumsum(marks)[:-1] > 0

    def interp(x):
        x = np.asarray(x, float)
        if np.all(np.isfinite(x)) and np.all(x == np.round(x)):
            # integer-valued (labels, counters): hold the last value instead of inventing fractions
            return x[np.clip(np.searchsorted(t, grid, side="right") - 1, 0, t.size - 1)]
        return np.interp(grid, t, x)

    direction = "down" if dt > 1.5 * med else ("up" if dt < med / 1.5 else "")
    msg = (
        f"resampled from {t.size} {'irregular ' if irregular.any() else ''}time stamps (median step {med:.6g} s) to {grid.size} "
        f"samples on a uniform {dt:g} s grid by linear interpolation"
    )
    if direction == "down":
        msg += " (downsampled without an anti-alias filter)"
    if gaps:
        lengths = d[gap_idx]
        k = int(np.argmax(lengths))
        msg += (
            f"; {len(gaps)} gap{'s' if len(gaps) > 1 else ''} longer than {(1 + dt_rtol) * dt:.6g} s bridged (lengths "
            f"{lengths.min():.3g}..{lengths.max():.3g} s, the longest at t = {gaps[k][0]:.6g} s), {int(in_gap.sum())} of "
            f"{grid.size} grid points ({in_gap.mean():.1%}) interpolated across missing data"
        )
        long = [(a, b) for (a, b), L in zip(gaps, lengths) if L >= LONG_GAP_STEPS * dt]
        if long:
            shown = ", ".join(f"{a:.6g}-{b:.6g} s" for a, b in long[:3]) + (f" and {len(long) - 3} more" if len(long) > 3 else "")
            msg += f"; long gaps (>= {LONG_GAP_STEPS} steps): {shown}"
    extra = {k: interp(v) for k, v in rec.extra.items()}
    return dataclasses.replace(
        rec,
        time=grid,
        u=np.interp(grid, t, rec.u),
        y=None if rec.y is None else np.interp(grid, t, rec.y),
        extra=extra,
        dt=dt,
        processing=(*rec.processing, msg),
        gaps=gaps,
    )


def _expand(paths) -> list[Path]:
    if isinstance(paths, (str, Path)):
        paths = [paths]
    out: list[Path] = []
    for p in paths:
        s = str(p)
        if any(c in s for c in "*?["):
            hits = sorted(Path(h) for h in _glob.glob(s, recursive=True) if Path(h).is_file())
            if not hits:
                raise DataError(s, "no file matches this pattern")
            out.extend(hits)
        elif Path(s).is_dir():
            hits = sorted(Path(s).glob("*.csv"))
            if not hits:
                raise DataError(s, "folder holds no .csv file")
            out.extend(hits)
        else:
            out.append(Path(s))
    seen, uniq = set(), []
    for p in out:
        key = p.resolve()
        if key not in seen:
            seen.add(key)
            uniq.append(p)
    return uniq


def load_records(paths, input: str | None = None, output: str | None = None, **kwargs) -> list[Record]:
    """Several records with one column choice: ``paths`` is a file, a folder (its ``*.csv``), a glob, or a list of them.

    All records must agree on the input and output columns and their units
    (sidecar ``units``); the first file that does not raises `DataError` naming
    it and the file it disagrees with.  Keyword arguments go to `load_record`.
    """
    files = _expand(paths)
    if not files:
        raise UserInputError("no record files given")
    recs: list[Record] = []
    for f in files:
        r = load_record(f, input, output, **kwargs)
        if recs:
            ref = recs[0]
            for role, a, b in (("input", r.input_name, ref.input_name), ("output", r.output_name, ref.output_name)):
                if a != b:
                    raise DataError(
                        f,
                        f"{role} column '{a}' differs from '{b}' in {ref.path}; all records need the same columns "
                        f"(choose with --{role} COLUMN)",
                    )
            for col in (r.input_name, r.output_name):
                ua, ub = r.units.get(col), ref.units.get(col)
                if ua and ub and ua != ub:
                    raise DataError(f, f"unit of '{col}' is {ua!r} here but {ub!r} in {ref.path}", column=col)
        recs.append(r)
    return recs
