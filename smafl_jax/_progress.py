"""Heartbeat lines on stderr for long phases that run inside one compiled call.

A solver loop compiled into one XLA ``while`` (optimistix LM, a vmapped scan)
cannot report from inside without slowing it down; a background thread prints
``label: N s elapsed`` every ``every_s`` seconds instead, so the user sees the
program is alive and how long the phase has taken.
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time

__all__ = ["heartbeat"]


@contextlib.contextmanager
def heartbeat(label: str, *, every_s: float = 10.0, enabled: bool = True, stream=None):
    """Print ``label: N s elapsed`` every ``every_s`` seconds while the block runs (nothing when ``enabled`` is false)."""
    if not enabled:
        yield
        return
    stop = threading.Event()
    t0 = time.monotonic()

    def beat():
        while not stop.wait(every_s):
            print(f"  {label}: {time.monotonic() - t0:.0f} s elapsed", file=stream or sys.stderr, flush=True)

    thread = threading.Thread(target=beat, name="smafl-heartbeat", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(timeout=1.0)
