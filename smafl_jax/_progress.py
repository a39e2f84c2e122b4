"""Progress of long phases, with a time estimate, reported through `logging`.

Library code never prints progress: it reports on the ``smafl_jax.progress``
logger at INFO level.  The ``smafl`` command line shows those lines on stderr
(`shown_on_stderr`); from Python, ``logging.basicConfig(level=logging.INFO)``
shows them.

- `Steps`: a phase made of N similar steps (null records, grid cells, report
  sections): ``label: k/N, 12 s elapsed, about 30 s left``, the estimate being
  the mean time per step so far times the steps left.
- `heartbeat`: a phase that runs inside one compiled call (an optimistix
  solve), which cannot report from inside without slowing it down; a
  background thread reports every few seconds instead.  Given a step count
  (`count_step`, called from the compiled loop through a host callback), it
  also reports the steps done and an upper bound of the time left (the
  solver may stop earlier than its step limit).
"""

from __future__ import annotations

import contextlib
import logging
import math
import sys
import threading
import time

__all__ = [
    "LOGGER",
    "Steps",
    "heartbeat",
    "count_step",
    "say",
    "shown",
    "shown_on_stderr",
    "format_seconds",
    "tagged",
    "current_tag",
]

LOGGER = logging.getLogger("smafl_jax.progress")

#: Tags of threads whose progress lines are prefixed (`tagged`), by thread identifier.
_TAGS: dict[int, str] = {}


class _TagFilter(logging.Filter):
    """Prefixes ``[tag]`` to the progress lines of a `tagged` thread: work running on several threads at once (the
    candidates of ``--model auto``) would otherwise interleave lines nobody can attribute."""

    def filter(self, record):
        tag = _TAGS.get(record.thread)
        if tag is not None and isinstance(record.msg, str):
            record.msg = f"[{tag}] {record.msg.lstrip()}"
        return True


LOGGER.addFilter(_TagFilter())


@contextlib.contextmanager
def tagged(tag: str):
    """Within this block, the calling thread's progress lines (and those of its `heartbeat` threads) start with
    ``[tag]``."""
    ident = threading.get_ident()
    before = _TAGS.get(ident)
    _TAGS[ident] = tag
    try:
        yield
    finally:
        if before is None:
            _TAGS.pop(ident, None)
        else:
            _TAGS[ident] = before


def current_tag() -> str | None:
    """The calling thread's `tagged` tag (None outside a block): work it hands to another thread keeps the prefix."""
    return _TAGS.get(threading.get_ident())


#: Least seconds between two progress lines of one phase (the last step is always reported).
EVERY_S = 5.0


def format_seconds(s: float) -> str:
    """``7 s``, ``2 min 05 s``, ``1 h 03 min``: a duration as a person reads it."""
    if not math.isfinite(s):
        return "? s"
    s = max(0.0, s)
    if s < 60:
        return f"{s:.0f} s"
    if s < 3600:
        m, r = divmod(round(s), 60)
        return f"{m} min {r:02d} s"
    h, r = divmod(round(s), 3600)
    return f"{h} h {r // 60:02d} min"


def _emit(msg: str, stream=None) -> None:
    if stream is not None:
        print(msg, file=stream, flush=True)
    else:
        LOGGER.info(msg)


class Steps:
    """Counted steps of one phase; `advance` after each step reports progress and the time left.

    Reports at most every ``every_s`` seconds (default `EVERY_S`) and always
    after the last step; the estimate is the mean duration of the steps so far,
    or, with ``weights`` (the relative cost of each step), the time per unit of
    weight so far.
    """

    def __init__(
        self, label: str, total: int, *, unit: str = "", every_s: float | None = None, enabled=True, stream=None, weights=None
    ):
        self.label, self.total, self.unit = label, int(total), unit
        self.weights = None if weights is None else [float(w) for w in weights]
        if self.weights is not None and len(self.weights) != self.total:
            raise ValueError(f"{len(self.weights)} weights for {self.total} steps")
        self.every_s = EVERY_S if every_s is None else every_s
        self.enabled, self.stream = enabled, stream
        self.done = 0
        self.t0 = time.monotonic()
        self._last = self.t0

    def elapsed(self) -> float:
        return time.monotonic() - self.t0

    def remaining(self) -> float:
        """Estimated seconds left (mean step duration so far x steps left); NaN before the first step."""
        if self.done <= 0:
            return float("nan")
        if self.weights is not None:
            done = sum(self.weights[: self.done])
            return self.elapsed() / done * sum(self.weights[self.done :]) if done > 0 else float("nan")
        return self.elapsed() / self.done * max(self.total - self.done, 0)

    def message(self, note: str = "") -> str:
        unit = f" {self.unit}" if self.unit else ""
        msg = f"  {self.label}: {self.done}/{self.total}{unit}, {format_seconds(self.elapsed())} elapsed"
        if self.done < self.total and self.done > 0:
            msg += f", about {format_seconds(self.remaining())} left"
        return msg + (f" ({note})" if note else "")

    def advance(self, n: int = 1, note: str = "") -> None:
        self.done += n
        now = time.monotonic()
        if self.enabled and (self.done >= self.total or now - self._last >= self.every_s):
            self._last = now
            _emit(self.message(note), self.stream)


# -- steps counted inside compiled loops ----------------------------------------------------------------


class _Counter:
    def __init__(self):
        self.n = 0
        self.first = None  # time of the first step: compile time is not part of the per-step estimate
        self.last = None

    def tick(self):
        now = time.monotonic()
        self.n += 1
        if self.first is None:
            self.first = now
        self.last = now


#: Step counters of the open `heartbeat` blocks that count steps, with the identifier of the thread that opened each.
_ACTIVE: list[tuple[int, _Counter]] = []


def count_step(*_args) -> None:
    """Host callback for one step of a compiled loop (``jax.debug.callback(count_step)``): counts it for the
    innermost `heartbeat` that asked for a step count, that of the calling thread when it has one (candidates
    fitted on several threads: the callback runs on the thread that called the compiled function); does nothing
    otherwise."""
    active = list(_ACTIVE)  # another thread may open or close a heartbeat meanwhile
    if active:
        ident = threading.get_ident()
        mine = [c for t, c in active if t == ident]
        (mine or [active[-1][1]])[-1].tick()


@contextlib.contextmanager
def heartbeat(label: str, *, every_s: float | None = None, enabled: bool = True, stream=None, max_steps: int | None = None):
    """Report ``label: N s elapsed`` every ``every_s`` seconds while the block runs (nothing when ``enabled`` is false).

    With ``max_steps``, evaluations counted by `count_step` (the first at the start point, then one per step)
    are reported too, with an upper bound of the time left: ``step k of at most M, at most R left`` (R from
    the mean step time so far, compiling excluded).
    """
    if not enabled:
        yield
        return
    every = EVERY_S if every_s is None else every_s
    stop = threading.Event()
    t0 = time.monotonic()
    counter = _Counter()
    entry = (threading.get_ident(), counter)
    if max_steps is not None:
        _ACTIVE.append(entry)
    tag = _TAGS.get(threading.get_ident())

    def beat():
        if tag is not None:
            _TAGS[threading.get_ident()] = tag
        while not stop.wait(every):
            msg = f"  {label}: {format_seconds(time.monotonic() - t0)} elapsed"
            n = counter.n - 1  # the first count is the evaluation at the start point (after compiling)
            if max_steps is not None and n > 0:
                per_step = (counter.last - counter.first) / n
                msg += f", step {min(n, max_steps)} of at most {max_steps}, at most {format_seconds(per_step * max(max_steps - n, 0))} left"
            _emit(msg, stream)

    thread = threading.Thread(target=beat, name="smafl-heartbeat", daemon=True)
    thread.start()
    try:
        yield counter
    finally:
        stop.set()
        if max_steps is not None:
            with contextlib.suppress(ValueError):
                _ACTIVE.remove(entry)
        thread.join(timeout=1.0)
        _TAGS.pop(thread.ident, None)


# -- showing progress (the command line) ---------------------------------------------------------------


class _StderrHandler(logging.Handler):
    """Writes records to the *current* ``sys.stderr`` (which test runners and callers may swap)."""

    def emit(self, record):
        try:
            print(self.format(record), file=sys.stderr, flush=True)
        except (OSError, ValueError):  # stderr closed or gone: progress is not worth failing for
            pass


def _reaches_a_handler() -> bool:
    """Whether progress records reach a handler (the command line's, the user's logging configuration, pytest's)."""
    logger = LOGGER
    while logger is not None:
        if any(not isinstance(h, logging.NullHandler) for h in logger.handlers):
            return True
        if not logger.propagate:
            return False
        logger = logger.parent
    return False


@contextlib.contextmanager
def shown(enabled: bool = True):
    """The ``progress=True`` / ``verbose=True`` of a library function: its progress lines are shown while the block runs.

    They go to the handlers logging is configured with (the command line's, or the user's); with none
    configured, to stderr.  A level set on the progress logger (``smafl ... --quiet``, or by the user) is
    respected; left unset, it is INFO while the block runs.  ``enabled=False`` changes nothing: the lines
    are then only logged, as every progress line of the library is.
    """
    if not enabled:
        yield
        return
    level, added = LOGGER.level, None
    if level == logging.NOTSET:
        LOGGER.setLevel(logging.INFO)
    if not _reaches_a_handler():
        added = _StderrHandler()
        added.setFormatter(logging.Formatter("%(message)s"))
        LOGGER.addHandler(added)
    try:
        yield
    finally:
        if added is not None:
            LOGGER.removeHandler(added)
        LOGGER.setLevel(level)


def say(msg: str, enabled: bool = True) -> None:
    """One progress line of a library function asked for progress (``enabled``): INFO on the progress logger,
    shown as `shown` says; nothing when ``enabled`` is false."""
    if enabled:
        with shown():
            LOGGER.info(msg)


@contextlib.contextmanager
def shown_on_stderr(enabled: bool = True):
    """Show progress lines on stderr while the block runs (``enabled=False``: hide them); the CLI wraps each
    command in it.  The logger's earlier state comes back afterwards (a command run inside another one,
    such as the paper's posterior run by `smafl sample --no-progress`, does not silence its caller).

    The library's notes and warnings (WARNING on the ``smafl_jax`` loggers, e.g. "resuming a stored chain")
    are shown too, as written, whatever ``enabled`` says: they are what Python's last-resort handler shows
    when logging is not configured, shown here even when it is (pytest, a program calling `cli.main`).
    """
    handler = _StderrHandler()
    handler.setFormatter(logging.Formatter("%(message)s"))
    before = (LOGGER.level, LOGGER.propagate, list(LOGGER.handlers))
    for h in before[2]:
        if isinstance(h, _StderrHandler):
            LOGGER.removeHandler(h)
    LOGGER.addHandler(handler)
    LOGGER.propagate = False  # shown once, by this handler, even when the root logger has handlers too
    LOGGER.setLevel(logging.INFO if enabled else logging.WARNING)
    library = logging.getLogger("smafl_jax")
    notes = _StderrHandler(logging.WARNING)
    notes.setFormatter(logging.Formatter("%(message)s"))
    outer_notes = [h for h in library.handlers if isinstance(h, _StderrHandler)]  # a command inside a command
    for h in outer_notes:
        library.removeHandler(h)
    library.addHandler(notes)
    try:
        yield
    finally:
        library.removeHandler(notes)
        for h in outer_notes:
            library.addHandler(h)
        LOGGER.removeHandler(handler)
        for h in before[2]:
            if h not in LOGGER.handlers:
                LOGGER.addHandler(h)
        LOGGER.setLevel(before[0])
        LOGGER.propagate = before[1]
