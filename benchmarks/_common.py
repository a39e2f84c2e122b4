"""Timing helpers and machine description shared by the benchmark sections.

Every figure is measured side by side in one process: warm-up call(s) first
(JIT / numba compilation excluded), then best-of-N wall time with
`time.perf_counter`; JAX results are forced with `jax.block_until_ready`
because dispatch is asynchronous.
"""

from __future__ import annotations

import datetime as _dt
import os
import platform
import sys
import time


def progress(msg):
    """Progress line on stderr (results go to files, not the terminal)."""
    print(f"[bench] {msg}", file=sys.stderr, flush=True)


def block(x):
    """Wait for asynchronous JAX results (no-op for numpy)."""
    try:
        import jax

        return jax.block_until_ready(x)
    except ImportError:  # pragma: no cover - jax is a hard dependency
        return x


def time_call(fn, *, repeat=3, warmup=1, min_total=None):
    """Best and median wall time (s) of ``fn()`` after ``warmup`` calls.

    ``fn`` must return its result; it is passed through `block` so JAX work
    is finished before the clock stops.  ``min_total`` keeps repeating very
    short calls until that many seconds were spent, so tiny records are not
    dominated by timer resolution.
    """
    for _ in range(warmup):
        block(fn())
    times = []
    spent = 0.0
    while len(times) < repeat or (min_total is not None and spent < min_total and len(times) < 1000):
        t0 = time.perf_counter()
        block(fn())
        dt = time.perf_counter() - t0
        times.append(dt)
        spent += dt
    times.sort()
    return {"best_s": times[0], "median_s": times[len(times) // 2], "n": len(times)}


def time_calls(fns, *, repeat=3, warmup=1, min_total=None):
    """Best wall time (s) of each ``fns[name]()``, measured round-robin.

    Interleaving the implementations (A, B, A, B, ...) instead of timing one
    after the other keeps a burst of load from other processes from landing
    on one side only; the side-by-side ratio is what we report.
    """
    for fn in fns.values():
        for _ in range(warmup):
            block(fn())
    best = {k: float("inf") for k in fns}
    spent, rounds = 0.0, 0
    while rounds < repeat or (min_total is not None and spent < min_total and rounds < 1000):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            block(fn())
            dt = time.perf_counter() - t0
            best[k] = min(best[k], dt)
            spent += dt
        rounds += 1
    return best


def _cpu_model():
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _mem_gib():
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemTotal:"):
                    return round(int(line.split()[1]) / 2**20, 1)
    except OSError:
        pass
    return None


def machine():
    """What the numbers were measured on (no absolute time without this)."""
    info = {
        "date_utc": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "cpu": _cpu_model(),
        "cpu_count": os.cpu_count(),
        "cpus_usable": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
        "memory_gib": _mem_gib(),
        "os": platform.platform(),
        "python": platform.python_version(),
    }
    for mod in ("jax", "jaxlib", "numpy", "numba", "scipy", "emcee"):
        try:
            info[mod] = __import__(mod).__version__
        except Exception as exc:  # report any import failure instead of crashing the run
            info[mod] = f"unavailable ({type(exc).__name__})"
    try:
        import jax

        info["jax_devices"] = ", ".join(f"{d.platform}:{d.device_kind}" for d in jax.devices())
    except Exception as exc:
        info["jax_devices"] = f"unavailable ({type(exc).__name__})"
    return info


def row(name, ours, baseline, unit, *, ratio=None, note="", **extra):
    """One result row in the common schema ``{name, ours, baseline, ratio, unit}``.

    ``ratio`` defaults to ``ours / baseline`` (for rates: > 1 means ours is
    faster).  Extra keys (sizes, raw seconds) are kept in results.json.
    """
    if ratio is None and ours is not None and baseline:
        ratio = ours / baseline
    out = {"name": name, "ours": ours, "baseline": baseline, "ratio": ratio, "unit": unit}
    if note:
        out["note"] = note
    out.update(extra)
    return out
