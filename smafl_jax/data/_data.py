"""Loading measured records: the entry point every CLI command uses, delegating to `smafl_jax.data.load`.

One reader for the whole package: `load_record` here keeps its historical
signature (``path, input, output, *, time, require_output, min_samples,
dt_rtol``) and adds ``resample``; the reading itself (UTF-8 byte-order mark,
cp1252 fallback, delimiter sniffing with decimal commas, JSON sidecar with
units / description / default columns / load, precise `DataError` messages
naming file, column and line) is `smafl_jax.data.load.load_record`.  `Record`
is `smafl_jax.data.record.Record`: the same fields as before plus
``processing`` (what was done on loading), ``gaps``, ``load`` and ``metadata``.

Irregular time stamps are refused with the fix in the message (``--resample
DT``) unless ``resample`` is given; then ``Record.processing`` says what was
done.
"""

from __future__ import annotations

import os

from .load import INPUT_CANDIDATES, OUTPUT_CANDIDATES, file_sha256
from .load import load_record as _load_record
from .record import DEFAULT_DT_RTOL, Record

__all__ = ["Record", "load_record", "file_sha256", "INPUT_CANDIDATES", "OUTPUT_CANDIDATES", "DEFAULT_DT_RTOL", "parse_resample"]


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
) -> Record:
    """Read and validate a record; ``input``/``output`` select columns (defaults: sidecar, then common names).

    ``resample``: None (irregular sampling is an error that names the gap and
    suggests ``--resample``), a sample time in seconds, or ``"auto"`` (the
    median step): linear interpolation onto a uniform grid, reported in
    ``Record.processing``.  ``row`` numbers in errors are file line numbers
    (the header is line 1).
    """
    return _load_record(
        path,
        input,
        output,
        time=time,
        require_output=require_output,
        min_samples=min_samples,
        dt_rtol=dt_rtol,
        resample=resample,
    )


def parse_window(text: str | None) -> tuple[float | None, float | None] | None:
    """The ``--window START:END`` option (seconds on the record's time axis, either side may be empty): None or
    ``(start, end)``; `UserInputError` otherwise."""
    import math

    from .._errors import UserInputError

    if text is None:
        return None
    parts = str(text).split(":")
    if len(parts) != 2 or not any(p.strip() for p in parts):
        raise UserInputError(f"--window needs START:END in seconds (either may be empty, e.g. 8.07: or :120), got {text!r}")
    try:
        lo, hi = (float(p) if p.strip() else None for p in parts)
    except ValueError:
        raise UserInputError(f"--window needs START:END in seconds, got {text!r}") from None
    if any(v is not None and not math.isfinite(v) for v in (lo, hi)):
        raise UserInputError(f"--window needs finite times, got {text!r}")
    if lo is not None and hi is not None and not lo < hi:
        raise UserInputError(f"--window START must be before END, got {text!r}")
    return lo, hi


def parse_resample(text: str | float | None) -> float | str | None:
    """The ``--resample`` option: None, ``"auto"`` or a positive number of seconds (`UserInputError` otherwise)."""
    import math

    from .._errors import UserInputError

    if text is None or text == "auto":
        return text
    try:
        dt = float(text)
    except (TypeError, ValueError):
        raise UserInputError(f"--resample needs a sample time in seconds or 'auto', got {text!r}") from None
    if not (math.isfinite(dt) and dt > 0):
        raise UserInputError(f"--resample needs a positive sample time in seconds, got {text!r}")
    return dt
