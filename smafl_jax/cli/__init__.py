"""Command-line interface: ``smafl <command> ...``.

Each command lives in its own module here with ``add_parser(subparsers)``
registering a parser whose ``func`` runs it.  Only the module of the command
being run is imported, so ``smafl --help`` and ``smafl --version`` answer
without importing JAX.

Exit codes: 0 success; 2 a user error (bad input, an output path that cannot
be written), printed as one line ``smafl CMD: error: ...`` without a
traceback; 130 interrupted (Ctrl-C); 143 terminated (SIGTERM).  After an error or an interrupt, output
folders this run created and left empty are removed.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import signal
import sys
import threading
import time
from pathlib import Path

# Command -> one-line help, in the order `smafl --help` lists them.  The same text is given by each
# module's add_parser (tests/test_reliability.py checks they agree); kept here so that the top-level
# help does not import the command modules (and JAX).
COMMANDS = {
    "simulate": "run a saved model (model file or fit.json) on an input record",
    "fit": "fit a model to a record: fit.json, report.md and figures",
    "sample": "posterior uncertainty of a fitted model by MCMC (emcee), with diagnostics and plots",
    "control": "closed-loop PID / composite PID (PID + I-I compensator) simulation",
    "sweep": "heat map of closed-loop e_mean over two swept parameters",
    "diagnose": "fit the base model, study its residuals, attribute and fit missing physical effects",
    "paper": "reproduce the paper end to end on the bundled data and write one report",
    "check": "check measured records for faults (offset jumps, spikes, flat runs, gaps, odd runs)",
}


def _version():
    from .. import __version__

    return __version__


class _UsageError(Exception):
    """A command line argparse rejects (reported by `main` as one line, exit 2)."""


class _Parser(argparse.ArgumentParser):
    """argparse, except that a usage error raises `_UsageError` instead of printing the usage and exiting."""

    def error(self, message):
        raise _UsageError(message)


def build_parser(command=None):
    """The ``smafl`` parser; only ``command``'s module is imported (all of them when ``command`` is ``"*"``)."""
    parser = _Parser(
        prog="smafl",
        description="System identification, uncertainty and control for hysteretic thermal artificial muscles.",
    )
    parser.add_argument("--version", action="version", version=f"smafl {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, help_text in COMMANDS.items():
        if command in (name, "*"):
            importlib.import_module(f"{__name__}.{name}").add_parser(sub)
        else:
            sub.add_parser(name, help=help_text)  # placeholder: the full parser is built when the command runs
    return parser


def _command_of(argv):
    """The sub-command named on the command line (the top-level parser has no options taking values)."""
    for a in argv:
        if not a.startswith("-"):
            return a if a in COMMANDS else None
    return None


def _flush():
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass


def _cleanup(reset=False):
    """Remove the empty output folders this run created (``reset``: forget earlier runs' folders instead)."""
    io = sys.modules.get(f"{__package__.rpartition('.')[0]}._io")  # not imported yet = nothing created
    if io is None:
        return
    if reset:
        io._CREATED_DIRS.clear()
    else:
        io.remove_created_dirs_if_empty()


def _created_note():
    """One line when this run created its output folder together with missing folders above it (``--out a/b/c`` where
    ``a`` did not exist): the user may not have meant to create a tree; a folder created alone needs no word."""
    io = sys.modules.get(f"{__package__.rpartition('.')[0]}._io")
    created = [Path(d) for d in getattr(io, "_CREATED_DIRS", [])]
    # the output folder: the deepest created folder on the path of every other (the command's own sub-folders below
    # it, such as `smafl paper`'s posterior/ and diagnosis_main_loop/, branch off and are not named)
    on_path = [d for d in created if all(d == e or d in e.parents or e in d.parents for e in created)]
    if not on_path:
        return
    leaf = max(on_path, key=lambda d: len(d.parts))
    above = sorted((d for d in created if d in leaf.parents), key=lambda d: len(d.parts))
    if above:
        shown = ", ".join(str(d) for d in above)
        print(f"note: created the folder {leaf} and the missing folders above it ({shown})", file=sys.stderr)


def _error_text(exc):
    if isinstance(exc, OSError):
        where = exc.filename if exc.filename is not None else ""
        return f"{where}: {exc.strerror}" if where and exc.strerror else str(exc)
    return str(exc)


def _blas_threads():
    """One BLAS thread for the command, unless the user set ``OPENBLAS_NUM_THREADS`` themselves (`smafl_jax._blas`).

    The variable acts when NumPy is not loaded yet (the program itself); threadpoolctl limits already loaded libraries
    (``main`` called in-process).  Measured on the 2-core machine under load: one Preisach cross-validation took 75 s
    with OpenBLAS's default threads and 8 s with one; `smafl fit datasets/steps.csv` 45 s -> 35 s.
    """
    from .._blas import one_blas_thread, set_blas_env

    set_blas_env()
    return one_blas_thread() if "numpy" in sys.modules else contextlib.nullcontext()


#: Seconds an interrupted command has to reach its own exit path before the watchdog ends it.
INTERRUPT_GRACE_S = 3.0
_exit_lock = threading.Lock()

# The command line being run (its words after ``smafl``) and the running command's words for an interrupt (what it
# kept and how to go on: `set_interrupt_note`), read by whichever thread reports the interrupt.
_run = {"argv": [], "note": None}


def set_interrupt_note(note):
    """Have an interrupt of this run say ``note()`` after ``interrupted`` (a callable returning a str or None).

    Called from the watchdog thread too: ``note`` must only read values in memory, never wait or touch files."""
    _run["note"] = note


def command_line(drop=()):
    """The command line being run, as one shell-quoted string starting ``smafl``, without the flags in ``drop``
    (value-less flags; an abbreviation argparse accepted counts as the flag)."""
    import shlex

    def dropped(a):
        return len(a) > 2 and a.startswith("--") and any(d.startswith(a) for d in drop)

    return shlex.join(["smafl", *(a for a in _run["argv"] if not dropped(a))])


def _interrupted_text(name):
    note = None
    if _run["note"] is not None:
        try:
            note = _run["note"]()
        except Exception:  # a faulty note must not stop the interrupt from ending the run
            note = None
    word = "terminated" if _run.get("terminated") else "interrupted"
    return f"{name}: {word}" + (f"; {note}" if note else "")


def _on_terminate(signum, frame):
    """SIGTERM (``kill``, ``timeout``, a batch scheduler) ends the run as Ctrl-C does: its empty output folders and
    temporary files removed, one line, exit 143 (Python's default for SIGTERM ends at once and left them behind)."""
    _run["terminated"] = True
    raise KeyboardInterrupt


def _interrupted_exit(name):
    """Clean up, say so and end the process with 130 (once, from whichever thread gets here first)."""
    if not _exit_lock.acquire(blocking=False):
        return
    _remove_temporary_files()  # first: a folder holding an unfinished write's temporary file is not empty
    _cleanup()
    try:
        print(_interrupted_text(name), file=sys.stderr)
    except (OSError, ValueError):
        pass
    _flush()
    os._exit(143 if _run.get("terminated") else 130)


def _remove_temporary_files():
    io = sys.modules.get(f"{__package__.rpartition('.')[0]}._io")
    if io is not None and hasattr(io, "remove_temporary_files"):
        io.remove_temporary_files()


def _install_interrupt_watchdog(name):
    """End the process at most `INTERRUPT_GRACE_S` after a Ctrl-C, whatever the main thread is doing.

    Python raises KeyboardInterrupt only when the main thread next runs Python code: not while it waits in
    a long compiled call (a JAX solve, an XLA compile), and the exception is lost when it fires inside a
    ``__del__`` or a weakref callback ("Exception ignored in ..."): the command then runs on as if never
    interrupted.  Python's C-level signal handler also writes the signal number to the wakeup file
    descriptor from any thread; a daemon thread waiting on it ends the process if the main thread has not
    done so within the grace period.  A second Ctrl-C ends it at once.
    """
    rfd, wfd = os.pipe()
    os.set_blocking(wfd, False)
    try:
        signal.set_wakeup_fd(wfd, warn_on_full_buffer=False)
    except ValueError:  # not the main thread: no watchdog
        os.close(rfd)
        os.close(wfd)
        return

    def watch():
        first = None
        while True:
            try:
                data = os.read(rfd, 64)
            except OSError:
                return
            if signal.SIGTERM in data:
                _run["terminated"] = True
            elif signal.SIGINT not in data:
                continue
            if first is not None:
                _interrupted_exit(name)  # second Ctrl-C
            first = time.monotonic()
            timer = threading.Timer(INTERRUPT_GRACE_S, _interrupted_exit, (name,))
            timer.daemon = True
            timer.start()

    threading.Thread(target=watch, name="smafl-interrupt-watchdog", daemon=True).start()
    previous = sys.unraisablehook

    def unraisable(hook_args):
        # a Ctrl-C that lands in a __del__ or a weakref callback cannot propagate ("Exception ignored in ...",
        # with a traceback); it is still the user's interrupt: end the run now
        if isinstance(hook_args.exc_value, KeyboardInterrupt):
            _interrupted_exit(name)
        previous(hook_args)

    sys.unraisablehook = unraisable


def main(argv=None):
    """Run ``smafl`` with ``argv`` (default: the process arguments); returns the exit code.

    When called as the program itself (``argv`` None), an interrupt ends the
    process with `os._exit` right after the message: letting the interpreter
    tear down while JAX's runtime threads are still busy can crash it (exit 139).
    A watchdog thread makes sure that happens within `INTERRUPT_GRACE_S` of the
    Ctrl-C even when the KeyboardInterrupt is delayed or lost.
    """
    from .._errors import UserInputError

    standalone = argv is None
    argv = list(sys.argv[1:] if argv is None else argv)
    command = _command_of(argv)
    name = f"smafl {command}" if command else "smafl"
    _run.update(argv=list(argv), note=None, terminated=False)
    _cleanup(reset=True)
    if standalone:
        _install_interrupt_watchdog(name)
        signal.signal(signal.SIGTERM, _on_terminate)
    try:
        parser = build_parser(command)
        args = parser.parse_args(argv)
        if not getattr(args, "func", None):
            parser.print_help()
            return 2
        from .._compile_cache import enable_persistent_cache
        from .._progress import shown_on_stderr

        # compiled programs kept on disk: a later run skips most compiling (`SMAFL_COMPILE_CACHE=off` disables it)
        enable_persistent_cache()
        quiet = getattr(args, "quiet", False) or getattr(args, "no_progress", False)
        with _blas_threads(), shown_on_stderr(not quiet):
            rc = int(args.func(args) or 0)
        _created_note()
        return rc
    except (UserInputError, OSError) as exc:
        _cleanup()
        print(f"{name}: error: {_error_text(exc)}", file=sys.stderr)
        return 2
    except _UsageError as exc:
        print(f"{name}: error: {exc} (`{name} --help` lists the options)", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        if standalone:
            _interrupted_exit(name)
        _remove_temporary_files()
        _cleanup()
        print(_interrupted_text(name), file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
