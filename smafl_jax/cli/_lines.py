"""How the commands show library log lines: plain lines on stderr while a command runs (the library only logs)."""

from __future__ import annotations

import contextlib
import logging


class _LineFormatter(logging.Formatter):
    """Log lines as the commands show them: warnings as ``warning: ...`` (or as written), the rest as written."""

    def __init__(self, warning_prefix: bool = True):
        super().__init__("%(message)s")
        self.warning_prefix = warning_prefix

    def format(self, record):
        msg = record.getMessage()
        return f"warning: {msg}" if self.warning_prefix and record.levelno >= logging.WARNING else msg


@contextlib.contextmanager
def workflow_lines_on_stderr(name: str = "smafl_jax.workflows", *, warning_prefix: bool = True):
    """Show the log lines of logger ``name`` (progress, notes, warnings) on stderr while the command runs."""
    from .._progress import _StderrHandler

    logger = logging.getLogger(name)
    handler = _StderrHandler()
    handler.setFormatter(_LineFormatter(warning_prefix))
    before = (logger.level, logger.propagate)
    logger.addHandler(handler)
    logger.propagate = False
    logger.setLevel(logging.INFO)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(before[0])
        logger.propagate = before[1]
