"""Parallel-in-time model evaluation: compile and run time of a forward pass by method (issue 15).

    python -m benchmarks.bench_parallel_time [--quick] [--sizes 1e4,1e5,1e6,1e7]

Workload: ``Cascade.simulate`` of the bundled truth model (datasets/truth.json: thermal lag +
EUPI with 24 operators) on a drive of T samples (dt = 0.01 s), with ``method`` = scan (one
``lax.scan`` step per sample), assoc (``lax.associative_scan`` over the whole record),
chunked (scan over 1024-sample blocks, associative inside) and segmented (128 pieces of the
record in lockstep, two passes); all four are exact (tests/test_parallel_time.py).  A second
workload is what a fit evaluates, the loss and its gradient for all parameters (value_and_grad;
scan and segmented only), and a third the EUPI alone with wide banks (50 and 200 operators) at
T = 1e5, where the segmented form is meant to pay off.

Compile: wall time of ``jax.jit(f).lower(u).compile()`` (trace + XLA compile), each method
once per size.  Run: best wall time of the compiled function, the methods timed round-robin
in the same process (`time_calls`) so that load from other processes hits all of them.
Each record length runs in its own subprocess with a time limit, so a form whose compile
runs away (assoc at T = 1e7 took 3 min on an H100, issue 15) is reported as cut off instead
of stalling the run; assoc at T = 1e7 is skipped when its prefix arrays alone would exceed
``ASSOC_MEMORY_GIB``.  Rows: ours = the method, baseline = scan in the same process;
ratio = scan seconds / method seconds (> 1: the method is faster than scan).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from benchmarks._common import progress, row, time_calls
else:
    from ._common import progress, row, time_calls

ROOT = Path(__file__).resolve().parents[1]
RATIO_MEANING = "scan seconds / method seconds, same process, round-robin (> 1: the parallel form is faster than scan)"
METHODS = ("scan", "assoc", "chunked", "segmented")
DT = 0.01
ASSOC_MEMORY_GIB = 3.0  # (lo, hi) prefix arrays of T x n float64: skip assoc above this (the machine is shared)
CHILD_TIMEOUT_S = 420


def _drive(T):
    """Deterministic 0..7.4 V drive: a slow sine with a faster one on top (minor loops), a few periods per record."""
    import numpy as np

    t = np.arange(T) / T
    return 3.7 + 3.0 * np.sin(2 * np.pi * 5 * t) + 0.7 * np.sin(2 * np.pi * 37 * t)


def _model(workload):
    import smafl_jax as sj

    truth = sj.load_model(ROOT / "datasets" / "truth.json")
    if workload == "cascade":
        return truth, 24
    n = int(workload.split(":")[1])  # "eupi:N": EUPI with N operators (N/5 symmetric, 4 tilts x N/5 asymmetric)
    k = n // 5
    import numpy as np

    m = sj.EUPI.from_range(0.0, 7.4, n_sym=k, n_alpha=4, n_asym=k)
    rng = np.random.default_rng(0)
    return m.with_linear_weights(rng.uniform(0.01, 0.1, m.linear_weights().shape[0])), m.n_operators


def _child(workload, T, methods, repeat):
    """Measure in this process; one JSON line per finding on stdout (the parent keeps what arrived before a cut-off)."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from smafl_jax.models import choose_model_method

    model, n_ops = _model(workload.removesuffix("-grad"))
    u = jnp.asarray(_drive(T))
    y_target = model.simulate(u, DT) if workload.endswith("-grad") else None
    print(json.dumps({"kind": "auto", "auto": choose_model_method(T, n_ops), "backend": jax.default_backend()}), flush=True)
    compiled, ref = {}, None
    for m in methods:
        variant = model.with_method(m) if workload.startswith("cascade") else _replace(model, m)
        if y_target is None:
            f = jax.jit(lambda x, variant=variant: variant.simulate(x, DT))
        else:  # what a fit evaluates: loss and gradient with respect to every parameter

            def loss(mod, x):
                return jnp.mean((mod.simulate(x, DT) - y_target) ** 2)

            def value_and_grad(x, variant=variant, loss=loss):
                value, g = jax.value_and_grad(loss)(variant, x)
                # every gradient leaf is returned, so XLA cannot drop any part of the backward pass
                return jnp.concatenate([value[None], *[jnp.ravel(leaf) for leaf in jax.tree.leaves(g)]])

            f = jax.jit(value_and_grad)
        t0 = time.perf_counter()
        c = f.lower(u).compile()
        t_compile = time.perf_counter() - t0
        t0 = time.perf_counter()
        y = np.asarray(jax.block_until_ready(c(u)))
        t_first = time.perf_counter() - t0
        ref = y if ref is None else ref
        diff = float(np.max(np.abs(y - ref)) / max(1.0, float(np.max(np.abs(ref)))))
        compiled[m] = c
        print(
            json.dumps({"kind": "compile", "method": m, "compile_s": t_compile, "first_run_s": t_first, "rel_diff": diff}),
            flush=True,
        )
    best = time_calls({m: (lambda c=c: c(u)) for m, c in compiled.items()}, repeat=repeat, warmup=0, min_total=0.5)
    print(json.dumps({"kind": "run", "best_s": best}), flush=True)


def _replace(model, method):
    import dataclasses

    return dataclasses.replace(model, method=method)


def _measure(workload, T, methods, repeat, timeout):
    """Findings of one subprocess (partial when it was cut off) and a note."""
    cmd = [sys.executable, "-m", "benchmarks.bench_parallel_time", "--child", workload, str(T), ",".join(methods), str(repeat)]
    env = dict(os.environ)
    env.setdefault("PYTHONPATH", str(ROOT))
    try:
        proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout)
        out, note = proc.stdout, "" if proc.returncode == 0 else f"child exited {proc.returncode}: {proc.stderr.strip()[-300:]}"
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
        note = f"cut off after {timeout} s"
    found = {"auto": None, "compile": {}, "run": {}}
    for line in out.splitlines():
        try:
            d = json.loads(line)
        except ValueError:
            continue
        if d.get("kind") == "auto":
            found["auto"] = d["auto"]
        elif d.get("kind") == "compile":
            found["compile"][d["method"]] = d
        elif d.get("kind") == "run":
            found["run"] = d["best_s"]
    return found, note


def _rows(workload, T, found, note, skipped):
    rows = []
    comp, run = found["compile"], found["run"]
    scan_c = comp.get("scan", {}).get("compile_s")
    scan_r = run.get("scan")
    label = {"cascade": "Cascade (24 ops)", "cascade-grad": "Cascade value+grad"}.get(
        workload
    ) or f"EUPI ({workload.split(':')[1]} ops)"
    for m in METHODS:
        if m not in comp and m not in skipped and workload.endswith("-grad"):
            continue
        if m in skipped:
            rows.append(row(f"{label} T={T:.0e} {m}", None, scan_r, "s", note=skipped[m], T=T, method=m))
            continue
        if m not in comp:
            rows.append(row(f"{label} T={T:.0e} {m}", None, scan_r, "s", note=note or "not measured", T=T, method=m))
            continue
        c = comp[m]
        r = run.get(m)
        extra = dict(T=T, method=m, workload=workload, compile_s=c["compile_s"], first_run_s=c["first_run_s"], auto=found["auto"])
        rows.append(
            row(
                f"{label} T={T:.0e} {m}: run",
                r,
                scan_r,
                "s",
                ratio=(scan_r / r) if (r and scan_r) else None,
                note=f"max |y - y_scan| / max|y| = {c['rel_diff']:.1e}"
                + (f"; auto picks {found['auto']}" if m == "scan" else ""),
                **extra,
            )
        )
        rows.append(
            row(
                f"{label} T={T:.0e} {m}: compile",
                c["compile_s"],
                scan_c,
                "s",
                ratio=(scan_c / c["compile_s"]) if scan_c else None,
                note="trace + XLA compile of the whole forward pass",
                **extra,
            )
        )
    return rows


def run(quick: bool = False, sizes=None) -> list[dict]:
    sizes = sizes or ((10_000, 100_000) if quick else (10_000, 100_000, 1_000_000, 10_000_000))
    rows, budget = [], {}
    for T in sizes:
        methods, skipped = [], {}
        for m in METHODS:
            est = budget.get(m)
            if m == "assoc" and 2 * T * 24 * 8 / 2**30 > ASSOC_MEMORY_GIB:
                skipped[m] = (
                    f"skipped: assoc prefix arrays {2 * T * 24 * 8 / 2**30:.1f} GiB > {ASSOC_MEMORY_GIB} GiB (shared machine)"
                )
            elif T >= 10_000_000 and est is not None and est > 60.0:
                skipped[m] = f"skipped: extrapolated compile + run {est:.0f} s > 60 s"
            else:
                methods.append(m)
        if "scan" not in methods:
            methods.insert(0, "scan")
        repeat = 20 if T <= 10_000 else 5 if T <= 100_000 else 3 if T <= 1_000_000 else 1
        progress(f"parallel_time: cascade T={T:.0e} methods {methods}")
        found, note = _measure("cascade", T, methods, repeat, CHILD_TIMEOUT_S)
        rows += _rows("cascade", T, found, note, skipped)
        for m, c in found["compile"].items():  # extrapolate to 10x the length: compile as measured, run x10
            budget[m] = c["compile_s"] + 10 * found["run"].get(m, c["first_run_s"])
    for T in () if quick else (10_000, 100_000):
        # the associative forms' gradients compile for minutes on 2 cores and run slower still: scan vs segmented only
        progress(f"parallel_time: cascade value+grad T={T:.0e}")
        found, note = _measure("cascade-grad", T, ["scan", "segmented"], 5, CHILD_TIMEOUT_S)
        rows += _rows("cascade-grad", T, found, note, {})
    for n in () if quick else (50, 200):
        T = 100_000
        progress(f"parallel_time: EUPI {n} operators T={T:.0e}")
        found, note = _measure(f"eupi:{n}", T, list(METHODS), 5, CHILD_TIMEOUT_S)
        rows += _rows(f"eupi:{n}", T, found, note, {})
    return rows


def _print(rows):
    print(f"{'benchmark':44s} {'method s':>10s} {'scan s':>10s} {'scan/method':>11s}  note")
    for r in rows:
        f = lambda x, fmt: "-" if x is None else format(x, fmt)
        print(
            f"{r['name']:44s} {f(r['ours'], '10.4g')} {f(r['baseline'], '10.4g')} {f(r['ratio'], '11.3g')}  {r.get('note', '')}"
        )


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m benchmarks.bench_parallel_time", description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="T = 1e4 and 1e5 only, no wide-bank rows")
    p.add_argument("--sizes", default=None, help="comma-separated record lengths, e.g. 1e4,1e5,1e6,1e7")
    p.add_argument("--child", nargs=4, metavar=("WORKLOAD", "T", "METHODS", "REPEAT"), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        workload, T, methods, repeat = args.child
        _child(workload, int(float(T)), methods.split(","), int(repeat))
        return 0
    sizes = tuple(int(float(s)) for s in args.sizes.split(",")) if args.sizes else None
    _print(run(args.quick, sizes))
    return 0


if __name__ == "__main__":
    sys.exit(main())
