"""Reading records from CSV files (+ optional JSON sidecar) with precise errors.

A record file is a CSV with a header row: a time column (``time_s``), an input
column and an output column; other numeric columns are kept in ``Record.extra``
(ambient temperature, load, branch labels...).  A sidecar ``NAME.json`` beside
``NAME.csv`` may give ``units`` (column -> unit), ``description``, default
``time`` / ``input`` / ``output`` column names and a per-record ``load`` (a number).

Reading rules (each documented, nothing changed silently):

- Leading lines starting with ``#`` (a logger's header) are skipped and counted.
- Time column: ``time`` (``--time COL``), else the sidecar's ``"time"``, else
  ``time_s``, else the one column whose name, lower-cased with its unit split
  off (``time [ms]``, ``time (s)``, ``t_ms``, ``Zeit [s]``), is one of
  `TIME_NAMES` with a unit of `TIME_UNITS` or none (a single upper-case ``T``
  is a temperature, not a time).  Its unit is the sidecar's ``units[COL]``,
  else the one in its name, else seconds; ms, us, min and h are converted to
  seconds.  Two candidates are an error listing both; ``processing`` says which
  column was read in which unit whenever it is not ``time_s`` in seconds.
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
  lines listed, up to 5).  An *optional* output (``require_output=False``, the
  measured column `smafl simulate` scores against) may have empty, NaN or
  infinite cells (`MISSING`): they are kept as NaN and ``processing`` counts
  them (a text cell there leaves it out, as any text column).  Other
  columns that are not numeric are left out of ``extra`` and ``processing``
  says so.
- Time stamps must increase strictly (duplicates and reversals name the line).
  With ``resample``, rows that repeat the row before in every cell (a logger
  writing a sample twice) are dropped and counted; a repeated time stamp with
  other values is an error either way (which row is right cannot be told).
- Irregular sampling (a step off the median step by more than ``dt_rtol``) is
  refused with the gap and the fix, unless ``resample=DT`` is given: the record
  is then interpolated linearly onto ``t0 + k DT`` (integer-valued extra columns
  such as branch labels are held, not interpolated).  Across a gap the linear
  interpolation *bridges* the gap (a straight line between the last sample
  before and the first after); a gap is a step of at least ``GAP_STEPS`` (1.5)
  sample times (and over ``1 + dt_rtol``), one that misses a sample: a
  jittered step of 1.3 sample times misses none, and its grid points are
  interpolations like any others between jittered stamps (counting it as a gap
  left a third of a 30 %-jittered record out of every fit).  Every bridged interval is kept in
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
import re
from pathlib import Path

import numpy as np

from smafl_jax._errors import DataError, UserInputError

from .names import is_voltage
from .record import DEFAULT_DT_RTOL, GAP_STEPS, Record, check_time, interpolated_mask

__all__ = [
    "load_record",
    "load_records",
    "file_sha256",
    "resample_record",
    "INPUT_CANDIDATES",
    "OUTPUT_CANDIDATES",
    "TIME_NAMES",
    "TIME_UNITS",
]

#: Column names taken as the input / output without --input / --output, first match wins (a drive voltage before a
#: directly measured input, so a file that also logs a temperature is still fitted from its voltage).
INPUT_CANDIDATES = ("voltage_V", "voltage", "input", "u", "temperature_C", "temperature", "pressure")
OUTPUT_CANDIDATES = ("displacement_mm", "displacement", "output", "y", "length_signal", "length_mm", "length")
DELIMITERS = (",", ";", "\t")
_DELIM_NAMES = {",": "comma", ";": "semicolon", "\t": "tab"}
#: Gaps at least this many sample times long are listed one by one in ``processing``.
LONG_GAP_STEPS = 10
#: The default time column; without it, a column named like one of `TIME_NAMES` (unit split off) is the time.
TIME_COLUMN = "time_s"
#: Names of a time column once lower-cased and stripped of their unit (English, German, French, Spanish, Italian).
TIME_NAMES = (
    "time",
    "t",
    "zeit",
    "timestamp",
    "elapsed",
    "elapsed time",
    "elapsed_time",
    "time_elapsed",
    "temps",
    "tiempo",
    "tempo",
)
#: Units of a time column: (multiplier, divisor) to seconds.  Dividing by 1000 (not multiplying by 0.001) gives the
#: correctly rounded seconds: "50" ms reads as exactly the float that "0.05" s does.
TIME_UNITS = {
    "s": (1, 1),
    "sec": (1, 1),
    "secs": (1, 1),
    "second": (1, 1),
    "seconds": (1, 1),
    "ms": (1, 1000),
    "msec": (1, 1000),
    "millisecond": (1, 1000),
    "milliseconds": (1, 1000),
    "us": (1, 1_000_000),
    "\u00b5s": (1, 1_000_000),
    "\u03bcs": (1, 1_000_000),
    "usec": (1, 1_000_000),
    "microsecond": (1, 1_000_000),
    "microseconds": (1, 1_000_000),
    "min": (60, 1),
    "h": (3600, 1),
}
_UNIT_WORDS = {1: "seconds", 1000: "milliseconds", 1_000_000: "microseconds", 60: "minutes", 3600: "hours"}
#: A date or a clock time in a cell ("2026-11-29 10:00:00.050", "10:00:01"): not seconds.
_DATE_TIME = re.compile(r"\d{1,4}[-./]\d{1,2}[-./]\d{1,4}|\d:\d\d")
#: Cells of an optional output column read as "no measurement" (lower-cased, stripped).
MISSING = ("", "nan", "na", "n/a", "null", "none")


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
    for key in ("time", "input", "output"):
        if meta.get(key) is not None and not isinstance(meta[key], str):
            raise DataError(side, f"'{key}' must be a column name (a string), got {meta[key]!r}")
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


def _sniff_delimiter(path: Path, header_line: str, line_no: int = 1) -> str:
    counts = {d: header_line.count(d) for d in DELIMITERS}
    best = max(DELIMITERS, key=lambda d: counts[d])
    if counts[best] == 0:
        raise DataError(
            path, f"cannot find a delimiter (comma, semicolon or tab) in the header line {header_line[:80]!r}", row=line_no
        )
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


def _pick(path, header, wanted, candidates, role, option, *, taken=(), notes=None, like=None, like_why=""):
    """The ``role`` column: ``wanted`` if named, else the first of ``candidates`` in the header, else the one column whose
    name without its unit is a candidate (``voltage (V)``, ``displacement [mm]``), else the one column ``like`` accepts
    (the input: a drive voltage by `names.is_voltage`, e.g. ``U`` or ``Spannung [V]``; the output: the only column left),
    ``like_why`` saying why; a column picked by the last two rules is named in ``notes``.  Messages name the CLI
    ``option`` and the Python keyword (``role``): `load_record` serves both."""
    choose = f"{option} COLUMN (Python: {role}=COLUMN)"
    if wanted is not None:
        if wanted not in header:
            raise DataError(path, f"no {role} column '{wanted}'; columns are {header}", column=wanted)
        return wanted
    found = [c for c in candidates if c in header]
    if found:
        return found[0]
    free = [c for c in header if c not in taken]
    for rule, why in (
        (lambda c: split_unit(c)[0] in {k.lower() for k in candidates}, "its name without the unit"),
        (like, like_why),
    ):
        hits = [c for c in free if rule is not None and rule(c)]
        if len(hits) == 1:
            if notes is not None:
                notes.append(f"{role} column '{hits[0]}' (recognised by {why}; {choose} to choose another)")
            return hits[0]
        if len(hits) > 1:
            raise DataError(path, f"several columns could be the {role}: {hits}; choose one with {choose}")
    raise DataError(path, f"cannot tell which column is the {role}; choose one of {header} with {choose}")


def _lines_text(lines) -> str:
    lines = [int(x) for x in lines]
    more = f" and {len(lines) - 5} more" if len(lines) > 5 else ""
    return ", ".join(str(x) for x in lines[:5]) + more


def split_unit(name: str) -> tuple[str, str | None]:
    """``(base, unit)`` of a column name, lower-cased: ``"time [ms]"`` -> ``("time", "ms")``, ``"t_s"`` -> ``("t", "s")``.

    A unit in brackets or parentheses at the end is split off whatever it is; one after ``_``, ``/`` or a space only
    when it is a time unit (``elapsed_time`` stays whole).
    """
    n = name.strip().lower()
    m = re.fullmatch(r"(.*?)\s*[\[(]\s*([^\])]*?)\s*[\])]", n)
    if m:
        return m.group(1).strip(), m.group(2)
    m = re.fullmatch(r"(.+?)[_/ ]([^_/ ]+)", n)
    if m and m.group(2) in TIME_UNITS:
        return m.group(1).strip(), m.group(2)
    return n, None


def _looks_like_time(name: str) -> bool:
    """A time column by its name: a time name with a time unit or none (``T`` alone is a temperature)."""
    base, unit = split_unit(name)
    if base not in TIME_NAMES or (unit is not None and unit not in TIME_UNITS):
        return False
    return not (base == "t" and name.strip()[:1] == "T")


def _time_column(path: Path, header: list[str], wanted: str | None, meta: dict, taken: set) -> tuple[str, tuple, str | None]:
    """The time column, its (multiplier, divisor) to seconds and a note saying how it was read (None: ``time_s`` in s)."""
    side = meta.get("time")
    if wanted is None and side is not None:
        wanted = side
    fix = 'choose the time column with --time COL (Python: time=COL; sidecar: "time": COL)'
    if wanted is not None:
        if wanted not in header:
            raise DataError(path, f"no time column '{wanted}'; columns are {header}; {fix}", column=wanted)
        col, how = wanted, "" if wanted == TIME_COLUMN else " (as chosen)"
    elif TIME_COLUMN in header:
        col, how = TIME_COLUMN, ""
    else:
        found = [h for h in header if h not in taken and _looks_like_time(h)]
        if len(found) > 1:
            raise DataError(path, f"several columns could be the time: {found}; {fix}")
        if not found:
            raise DataError(
                path,
                f"no time column '{TIME_COLUMN}' (nor one named like time, t or timestamp with a unit s, ms or us, such as "
                f"'time [ms]' or 't_s'); columns are {header}; {fix} (a unit in its name or the sidecar's units, else seconds)",
                column=TIME_COLUMN,
            )
        col, how = found[0], " (recognised by its name)"
    unit_side = (meta.get("units") or {}).get(col)
    if unit_side is not None:
        unit, source = str(unit_side).strip().lower(), "the sidecar's units"
        if unit not in TIME_UNITS:
            raise DataError(
                path.with_suffix(".json"),
                f"units['{col}'] = {unit_side!r} is not a time unit (one of s, ms, us, min, h)",
                column=col,
            )
    else:
        unit, source = split_unit(col)[1], "its name"
        if unit is not None and unit not in TIME_UNITS:
            raise DataError(
                path,
                f"the unit '{unit}' in the time column's name is not a time unit (s, ms, us, min, h); give its unit in the "
                f'sidecar\'s units ("units": {{"{col}": "ms"}})',
                column=col,
            )
    scale = TIME_UNITS.get(unit, (1, 1)) if unit is not None else (1, 1)
    if col == TIME_COLUMN and scale == (1, 1):
        return col, scale, None
    if unit is None:
        return col, scale, f"time column '{col}'{how} has no unit in its name: read as seconds"
    if scale == (1, 1):
        return col, scale, f"time column '{col}'{how} read as seconds (unit from {source})"
    word = _UNIT_WORDS[scale[0] * scale[1]]
    return col, scale, f"time column '{col}'{how} read as {word} (unit from {source}) -> seconds"


def _skip_comments(text: str) -> tuple[str, int]:
    """``text`` with its leading ``#`` lines blanked (line numbers kept) and how many there were."""
    lines = text.splitlines()
    n = 0
    for i, ln in enumerate(lines):
        s = ln.strip()
        if not s:
            continue
        if not s.startswith("#"):
            break
        lines[i] = ""
        n += 1
    return ("\n".join(lines), n) if n else (text, 0)


def _optional_column(cells: list[str], decimal_comma: bool) -> tuple[np.ndarray | None, np.ndarray, int]:
    """An optional output column: ``(values, missing indices, -1)`` with empty, NaN and infinite cells as NaN, or
    ``(None, [], j)`` when cell ``j`` is not a number (the column is then left out, like any other text column)."""
    missing = np.array([c.strip().lower() in MISSING for c in cells], bool)
    filled = ["nan" if m else c for c, m in zip(cells, missing)]
    x = _to_float(filled, decimal_comma)
    if x is None:
        return None, np.empty(0, int), _first_bad_cell(filled, decimal_comma)
    gone = ~np.isfinite(x)  # "nan" and "inf" cells too: no measurement
    x[gone] = np.nan
    return x, np.flatnonzero(gone), -1


def _same_row(body: list[list[str]], k: int, cols: dict, header: list[str]) -> list[str]:
    """The columns in which row ``k`` differs from row ``k - 1`` (numbers compared as numbers, NaN equal to NaN)."""
    differ = []
    for i, h in enumerate(header):
        if h in cols:
            a, b = cols[h][k - 1], cols[h][k]
            if not (a == b or (np.isnan(a) and np.isnan(b))):
                differ.append(h)
        elif body[k - 1][i].strip() != body[k][i].strip():
            differ.append(h)
    return differ


def _duplicates(path, t, body, lines, cols, header, col, resample):
    """Indices of exact duplicate rows to drop (``resample`` given) or `DataError` (module docstring)."""
    dup = np.flatnonzero(np.diff(t) == 0) + 1
    if not dup.size:
        return dup
    differ = {int(k): _same_row(body, int(k), cols, header) for k in dup}
    other = [k for k in dup if differ[int(k)]]
    exact = [k for k in dup if not differ[int(k)]]
    if other:
        k = int(other[0])
        also = f", and {len(exact)} exact duplicate row{'s' if len(exact) != 1 else ''}" if exact else ""
        raise DataError(
            path,
            f"duplicated time value {float(t[k]):g} with different values in {differ[k]} (lines {lines[k - 1]} and "
            f"{lines[k]}; {len(other)} such repeated time stamp{'s' if len(other) != 1 else ''} in all{also}): which row is "
            "right cannot be told from the file; delete one of the two rows, or replace them by one row with their average, "
            "then load again",
            column=col,
            row=lines[k],
        )
    if resample is None:
        k = int(exact[0])
        raise DataError(
            path,
            f"duplicated time value {float(t[k]):g}: line {lines[k]} repeats line {lines[k - 1]} in every cell "
            f"({len(exact)} exact duplicate row{'s' if len(exact) != 1 else ''} in all, lines {_lines_text([lines[j] for j in exact])}); "
            "delete the repeated rows, or load with --resample auto (or DT; Python: resample=...), which drops exact "
            "duplicate rows and reports it",
            column=col,
            row=lines[k],
        )
    return np.asarray(exact, int)


def load_record(
    path: str | os.PathLike,
    input: str | None = None,
    output: str | None = None,
    *,
    time: str | None = None,
    require_output: bool = True,
    min_samples: int = 10,
    dt_rtol: float = DEFAULT_DT_RTOL,
    resample: float | str | None = None,
    irregular: str = "error",
) -> Record:
    """Read and validate one record (rules in the module docstring).

    ``input``/``output``/``time`` select columns (defaults: the sidecar's, then
    common names; for the time ``time_s``, then a column named like a time).
    ``require_output=False``: the output is optional (the measured column of a
    simulation): read when named (``output``) and present, with empty, NaN or
    infinite cells kept as NaN (counted in ``processing``); absent or not
    numeric, ``y`` and ``output_name`` are None (``processing`` says why).
    ``resample``: a sample time in seconds, or ``"auto"`` (the median
    step), to put irregular stamps on a uniform grid (exact duplicate rows are
    dropped first, and reported).  ``irregular="keep"``
    keeps irregular stamps as they are (``dt`` = median step) for `check_record`
    to report; models need a uniform grid, so fitting code leaves it at
    ``"error"``.  ``row`` numbers in errors are file line numbers (the header's
    is 1 unless comment lines come before it).
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
    text, n_comments = _skip_comments(text)
    if n_comments:
        notes.append(f"skipped {n_comments} comment line{'s' if n_comments > 1 else ''} (starting with '#') before the header")
    first_no, first = next(((i + 1, ln) for i, ln in enumerate(text.splitlines()) if ln.strip()), (None, None))
    if first is None:
        raise DataError(path, "file holds only comment lines" if n_comments else "file is empty")
    delim = _sniff_delimiter(path, first, first_no)
    decimal_comma = delim != ","
    rows, lines = _parse_rows(path, text, delim)
    header = [h.strip() for h in rows[0]]
    head_line = lines[0]
    body, lines = rows[1:], lines[1:]
    # a trailing delimiter on every line (some exports) gives an unnamed, empty last column
    if header and header[-1] == "" and all(len(r) == len(header) and not r[-1].strip() for r in body):
        header, body = header[:-1], [r[:-1] for r in body]
        notes.append("empty unnamed last column (trailing delimiters) ignored")
    if "" in header:
        raise DataError(path, f"empty column name at position {header.index('') + 1} of the header {header}", row=head_line)
    if len(set(header)) != len(header):
        raise DataError(path, f"duplicated column names in header {header}", row=head_line)
    if not body:
        raise DataError(path, "header only, no data rows")
    named = {c for c in (input, output, meta.get("input"), meta.get("output")) if c is not None}
    time, t_scale, t_note = _time_column(path, header, time, meta, named)
    if t_note:
        notes.append(t_note)
    in_col = _pick(
        path, header, input if input is not None else meta.get("input"), INPUT_CANDIDATES, "input", "--input",
        taken={time, output, meta.get("output")} - {None}, notes=notes, like=is_voltage,
        like_why="its name or unit, a voltage",
    )  # fmt: skip
    out_col = None
    optional = None  # the optional output column: empty / NaN cells allowed
    if require_output:
        out_col = _pick(
            path, header, output if output is not None else meta.get("output"), OUTPUT_CANDIDATES, "output", "--output",
            taken={time, in_col}, notes=notes, like=lambda c: len(header) == 3, like_why="being the only column left",
        )  # fmt: skip
    elif output is not None and output in header:
        out_col = optional = output
    if out_col is not None and out_col == in_col:
        raise DataError(path, f"input and output are the same column '{in_col}'")
    if in_col == time or out_col == time:
        raise DataError(path, f"the time column '{time}' cannot also be the input or output")
    for row, line in zip(body, lines):
        if len(row) != len(header):
            raise DataError(path, f"expected {len(header)} cells, found {len(row)}", row=line)
    required = [time, in_col] + ([out_col] if out_col and out_col != optional else [])
    cols: dict[str, np.ndarray] = {}
    for i, h in enumerate(header):
        cells = [r[i] for r in body]
        if h == optional:
            x, gone, j = _optional_column(cells, decimal_comma)
            if x is None or gone.size == x.size:
                why = "holds no number" if x is not None else f"is not numeric (line {lines[j]}: {cells[j].strip()[:20]!r})"
                notes.append(f"output column '{h}' {why}: left out, no measured output")
                out_col = None
                continue
            if gone.size:
                notes.append(
                    f"output column '{h}': {gone.size} of {x.size} cells empty or not finite (first at line "
                    f"{lines[gone[0]]}): kept as NaN (no measurement there)"
                )
            cols[h] = x
            continue
        x = _to_float(cells, decimal_comma)
        if x is None:
            j = _first_bad_cell(cells, decimal_comma)
            if h in required:
                if cells[j].strip():
                    what = f"non-numeric value {cells[j].strip()[:40]!r}"
                else:
                    blank = [lines[k] for k, c in enumerate(cells) if not c.strip()]
                    what = "empty cell" + (f" ({len(blank)} in all, lines {_lines_text(blank)})" if len(blank) > 1 else "")
                if h == time and cells[j].strip():
                    what += (
                        " (date-time stamps are not read: convert the column to seconds, e.g. since the first stamp)"
                        if _DATE_TIME.search(cells[j])
                        else " (the time column must hold numbers: seconds, or ms / us with the unit in its name)"
                    )
                raise DataError(path, what, column=h, row=lines[j])
            blank = [k for k, c in enumerate(cells) if c.strip().lower() in MISSING]
            if blank and _to_float(["nan" if c.strip().lower() in MISSING else c for c in cells], decimal_comma) is not None:
                notes.append(
                    f"column '{h}' has {len(blank)} empty or NaN cell{'s' if len(blank) > 1 else ''} (first at line "
                    f"{lines[blank[0]]}): left out"
                )
            else:
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
    if t_scale != (1, 1):
        cols[time] = cols[time] * t_scale[0] / t_scale[1]
    drop = _duplicates(path, cols[time], body, lines, cols, header, time, resample)
    if drop.size:
        notes.append(
            f"dropped {drop.size} exact duplicate row{'s' if drop.size > 1 else ''} (every cell equal to the row before; "
            f"lines {_lines_text([lines[k] for k in drop])}) before resampling"
        )
        keep = np.ones(len(body), bool)
        keep[drop] = False
        cols = {h: x[keep] for h, x in cols.items()}
        lines = [ln for ln, k in zip(lines, keep) if k]
    if len(lines) < min_samples:
        raise DataError(path, f"too few samples: {len(lines)} rows, need at least {min_samples}")
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
        extra={h: v for h, v in cols.items() if h not in required and h != out_col},
        units=dict(meta.get("units", {})),
        description=str(meta.get("description", "")),
        path=str(path),
        sha256=hashlib.sha256(raw).hexdigest(),
        processing=tuple(notes),
        load=None if meta.get("load") is None else float(meta["load"]),
        metadata=meta,
        time_name=time,
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
    gap_step = max(1 + dt_rtol, GAP_STEPS) * dt
    gap_idx = np.flatnonzero(d >= gap_step)
    gaps = tuple((float(t[k]), float(t[k + 1])) for k in gap_idx)
    in_gap = interpolated_mask(grid, gaps, dt)  # grid points inside a bridged interval: interpolated across missing data

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
            f"; {len(gaps)} gap{'s' if len(gaps) > 1 else ''} of {gap_step:.6g} s or longer bridged (lengths "
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
        as_read=rec if rec.as_read is None else rec.as_read,  # resampled twice: the stamps of the file
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
