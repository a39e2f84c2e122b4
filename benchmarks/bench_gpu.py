"""GPU vs CPU, side by side in one process: the same jitted public entry points on both devices.

    python benchmarks/bench_gpu.py [--quick] --out DIR [--budget-s 330] [--only play,batch,sweep,posterior]
    python benchmarks/bench_gpu.py --render --out DIR      # print the table of DIR/results.json again

Sections (float64 throughout, the toolkit's public API):

* ``play``: one record through the play-operator bank, `smafl_jax.play_scan` vs `smafl_jax.play_assoc`
  (and `smafl_jax.ops.play_chunked`), n in {24, 200} operators, T in {1e4, 1e5, 1e6} samples;
  op-steps/s.  The parallel forms run on the CPU only up to T*n = 5e7 (they are 5-100x slower there).
* ``batch``: `smafl_jax.simulate_batch` of the bundled truth cascade (datasets/truth.json, 24 operators)
  on B in {1, 64, 1024, 8192} records x T = 1e4; record-steps/s.
* ``sweep``: `smafl_jax.sweep` (closed-loop PID + I-I compensator on the truth plant, 1000 steps)
  over a (Kp, Ki) grid of 16, 256, 4096 configurations; closed-loop steps/s.
* ``posterior``: `smafl_jax.Posterior` called on a batch of walkers (the jit(vmap(log_prob)) emcee
  uses with ``vectorize=True``), full cascade on datasets/main_loop.csv, 32, 512, 8192 walkers; evals/s.

Placement: inputs are committed with `jax.device_put` where the entry point takes arrays, and each
call runs under `jax.default_device` so arrays the toolkit makes inside land on the same device.
Timing: the first call (compile + run) is timed, then repeated calls until ``TARGET_S`` seconds or
``MAX_REPS`` calls (at least 3 when a call is short, 1 when long); the median is kept and
``compile_s`` = first call - median.  Every result is brought back to the host (for the GPU-vs-CPU
``max_abs_diff``), outside the timed calls.  Sizes run smallest first across all sections, then the
next size everywhere, so a time budget (``--budget-s``) cut still leaves every section measured; a
case whose predicted time would cross the budget is skipped and listed.  ``results.json`` is
rewritten (atomically) after every case, so a run killed from outside keeps what it measured.
Without a GPU the CPU alone is timed and the table says so.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGET_S = 0.5  # keep repeating a call until this much time was spent on it ...
MAX_REPS = 7  # ... or this many timed calls
LONG_CALL_S = 1.0  # a first call longer than this gets a single timed repeat
PARALLEL_CPU_MAX_WORK = 5e7  # assoc/chunked on the CPU above T*n: minutes per call and several GB (benchmarks/README.md)
MEM_CAP_BYTES = 8 * 2**30  # per-device working set cap for the batched sections
DT = 0.01
SECTIONS = ("play", "batch", "sweep", "posterior")

SIZES = {
    False: {
        "play_n": (24, 200),
        "play_T": (10_000, 100_000, 1_000_000),
        "batch_B": ((1, 64), (1024,), (8192,)),
        "batch_T": 10_000,
        "sweep_side": ((4,), (16,), (64,)),
        "sweep_duration_s": 10.0,
        "walkers": ((32,), (512,), (8192,)),
    },
    True: {
        "play_n": (8, 24),
        "play_T": (300, 1_000, 3_000),
        "batch_B": ((1, 4), (16,), (32,)),
        "batch_T": 300,
        "sweep_side": ((2,), (3,), (4,)),
        "sweep_duration_s": 0.5,
        "walkers": ((4,), (16,), (32,)),
    },
}


def progress(msg: str) -> None:
    print(f"[bench_gpu {time.strftime('%H:%M:%S')}] {msg}", flush=True)


class Budget:
    """Wall-clock budget; predicts a case from the last seconds-per-work of the same kind."""

    def __init__(self, limit_s: float):
        self.t0, self.limit = time.perf_counter(), float(limit_s)
        self.per_work: dict = {}  # key -> (seconds per unit of work, compile seconds)
        self.skipped: list[str] = []

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def predict(self, key, work: float) -> float | None:
        if key not in self.per_work:
            return None
        spw, comp = self.per_work[key]
        run = spw * work
        return comp + run * (2 if run > LONG_CALL_S else 4)

    def allows(self, key, work: float, label: str) -> bool:
        pred = self.predict(key, work)
        left = self.limit - self.elapsed()
        if left <= 0 or (pred is not None and pred > left):
            why = f"{label}: skipped, budget ({self.elapsed():.0f} s used of {self.limit:.0f} s" + (
                f", predicted {pred:.0f} s)" if pred is not None else ")"
            )
            self.skipped.append(why)
            progress(why)
            return False
        return True

    def learn(self, key, work: float, seconds: float, compile_s: float) -> None:
        self.per_work[key] = (seconds / max(work, 1.0), compile_s)


def _block(x):
    import jax

    return jax.block_until_ready(x)


def measure(fn):
    """(result, first-call seconds, median seconds, repeats) of ``fn()``; results are forced with block_until_ready."""
    t0 = time.perf_counter()
    out = _block(fn())
    first = time.perf_counter() - t0
    min_reps = 1 if first > LONG_CALL_S else 3
    times: list[float] = []
    while len(times) < min_reps or (sum(times) < TARGET_S and len(times) < MAX_REPS):
        t0 = time.perf_counter()
        _block(fn())
        times.append(time.perf_counter() - t0)
    return out, first, statistics.median(times), len(times)


def _host(x):
    import numpy as np

    return np.asarray(x, dtype=np.float64)


def _max_abs_diff(a, b) -> float | None:
    import numpy as np

    if a is None or b is None:
        return None
    if a.shape != b.shape:
        return math.inf
    return float(np.max(np.abs(a - b))) if a.size else 0.0


def _atomic_json(path: Path, obj) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as fh:
            json.dump(obj, fh, indent=1, default=str)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


# -- devices -------------------------------------------------------------------------------------


def _devices(fake_accel: bool):
    """{"cpu": device, "gpu": device or None} and a note; ``fake_accel`` uses a second host device as the 'gpu'."""
    import jax

    cpu = jax.devices("cpu")[0]
    if fake_accel:
        return {"cpu": cpu, "gpu": jax.devices("cpu")[1]}, "fake accelerator: second host CPU device (test of the placement)"
    try:
        gpus = jax.devices("gpu")
    except Exception as exc:  # no CUDA/ROCm backend in this jaxlib, or it failed to start (RuntimeError in JAX 0.4-0.10)
        return {"cpu": cpu, "gpu": None}, f"no GPU: {str(exc).splitlines()[0][:160]}"
    return {"cpu": cpu, "gpu": gpus[0]}, ""


@contextlib.contextmanager
def on(dev):
    """Run under ``dev`` as the default device (arrays the toolkit makes inside land there)."""
    import jax

    if hasattr(jax, "default_device"):
        with jax.default_device(dev):
            yield
        return
    old = jax.config.jax_default_device  # fallback should a JAX release drop the context manager
    jax.config.update("jax_default_device", dev)
    try:
        yield
    finally:
        jax.config.update("jax_default_device", old)


def _placement_check(devs) -> str:
    """A jitted call on uncommitted host arrays under `on(dev)` must run on ``dev``."""
    import jax
    import jax.numpy as jnp

    x = jnp.arange(4.0)
    bad = []
    for name, dev in devs.items():
        if dev is None:
            continue
        with on(dev):
            y = jax.jit(lambda a: a * 2.0)(x)
            z = jnp.ones(3)
        if y.devices() != {dev} or z.devices() != {dev}:
            bad.append(f"{name}: jit ran on {y.devices()}, jnp.ones on {z.devices()}, wanted {dev}")
    return "; ".join(bad) or "ok"


def _put(tree, dev):
    """Commit the array leaves of a PyTree (e.g. an eqx model) to ``dev``; non-array leaves untouched."""
    import equinox as eqx
    import jax

    arrays, static = eqx.partition(tree, eqx.is_array)
    return eqx.combine(jax.device_put(arrays, dev), static)


def _check_on(out, dev) -> str:
    devices = getattr(out, "devices", None)
    if devices is None:
        return ""
    got = devices()
    return "" if got == {dev} else f"output on {sorted(map(str, got))}, expected {dev}"


# -- the runner ----------------------------------------------------------------------------------


class Runner:
    def __init__(self, out_dir: Path, devs: dict, budget: Budget, meta: dict):
        self.out_dir, self.devs, self.budget, self.meta = out_dir, devs, budget, meta
        self.rows: list[dict] = []
        self.refs: dict = {}  # ref_key -> host result of the first CPU run of that case

    def save(self) -> None:
        meta = dict(self.meta, elapsed_s=round(self.budget.elapsed(), 2), skipped=list(self.budget.skipped))
        _atomic_json(self.out_dir / "results.json", {"meta": meta, "rows": self.rows})

    def case(self, section, case, method, work, unit, fn_of_device, ref_key=None, pred=None):
        """Time ``fn_of_device(dev)()`` on the CPU then the GPU; rows with throughput, GPU/CPU ratio and max |diff|.

        ``fn_of_device(dev)`` returns the call to time, or a string: the reason it is not run there.
        ``ref_key``: results of the same case under another method are compared with its CPU result
        (the first one measured) so that every form is checked against the same reference.
        ``pred``: (extra key, work) for the budget's prediction when cost does not scale with ``work``.
        """
        results = {}
        for dname in ("cpu", "gpu"):
            dev = self.devs[dname]
            if dev is None:
                continue
            key = (section, method, dname) + (() if pred is None else (pred[0],))
            pwork = work if pred is None else pred[1]
            label = f"{section} {case} {method} [{dname}]"
            row = dict(section=section, case=case, method=method, device=dname, work=work, unit=unit)
            if not self.budget.allows(key, pwork, label):
                row.update(seconds=None, note="skipped: time budget")
                self.rows.append(row)
                continue
            try:
                with on(dev):
                    fn = fn_of_device(dev)
                    if isinstance(fn, str):  # a reason not to run this form on this device
                        row.update(seconds=None, note=fn)
                        self.rows.append(row)
                        progress(f"{label}: not run ({fn})")
                        continue
                    progress(f"{label}: running")
                    out, first, med, reps = measure(fn)
                    note = _check_on(out, dev)
                    host = _host(out)
                    del out, fn
            except Exception as exc:  # one failing case is reported; the others still run
                msg = f"{type(exc).__name__}: {str(exc).splitlines()[0][:200] if str(exc) else ''}"
                row.update(seconds=None, note=f"failed: {msg}")
                self.rows.append(row)
                progress(f"{label}: FAILED {msg}")
                self.save()
                continue
            comp = max(first - med, 0.0)
            self.budget.learn(key, pwork, med, comp)
            row.update(seconds=med, first_call_s=first, compile_s=comp, reps=reps, throughput=work / med, note=note)
            results[dname] = (row, host)
            self.rows.append(row)
            progress(f"{label}: {med:.4g} s/call, compile {comp:.3g} s, {work / med:.3g} {unit} ({reps} reps)")
        ref = self.refs.get(ref_key) if ref_key is not None else None
        if ref is None and "cpu" in results:
            ref = results["cpu"][1]
            if ref_key is not None:
                self.refs[ref_key] = ref
        for row, host in results.values():
            row["max_abs_diff"] = _max_abs_diff(host, ref) if ref is not None else None
        if "cpu" in results and "gpu" in results:
            results["gpu"][0]["ratio"] = results["gpu"][0]["throughput"] / results["cpu"][0]["throughput"]
        self.save()
        return results


# -- sections ------------------------------------------------------------------------------------


def _signal(rng, T):
    import numpy as np

    # random reversals between 0 and 1 (minor loops of all sizes), as in bench_operators
    knots = rng.uniform(0.0, 1.0, max(T // 50, 2))
    return np.interp(np.linspace(0, len(knots) - 1, T), np.arange(len(knots)), knots)


def _drives(B, T, seed=0):
    """(B, T) drive voltages 0..7.4 V: a slow sine with a faster one on top, a random phase per record."""
    import numpy as np

    rng = np.random.default_rng(seed)
    t = np.arange(T)[None, :] / T
    ph = rng.uniform(0, 2 * np.pi, (B, 1))
    return 3.7 + 3.0 * np.sin(2 * np.pi * 5 * t + ph) + 0.7 * np.sin(2 * np.pi * 37 * t + 2 * ph)


def _fmt(T) -> str:
    e = int(round(math.log10(T))) if T > 0 else 0
    return f"1e{e}" if 10**e == T else str(T)


def play_cases(quick: bool, tier: int):
    sz = SIZES[quick]
    T = sz["play_T"][tier]
    return [(n, T) for n in sz["play_n"]]


def run_play(runner: Runner, quick: bool, tier: int):
    import jax
    import numpy as np

    import smafl_jax as sj
    from smafl_jax import ops

    fns = {
        "scan": jax.jit(lambda u, r, a, y0: sj.play_scan(u, r, a, y0)),
        "assoc": jax.jit(lambda u, r, a, y0: sj.play_assoc(u, r, a, y0)),
        "chunked": jax.jit(lambda u, r, a, y0: ops.play_chunked(u, r, a, y0)),
    }
    rng = np.random.default_rng(tier)
    for n, T in play_cases(quick, tier):
        u = _signal(rng, T)
        r = np.arange(1, n + 1) / (2.0 * n)
        a = np.geomspace(0.4, 2.5, n)
        y0 = np.zeros(n)
        work = float(n) * T
        case = f"n={n} T={_fmt(T)}"
        scan_s = {}
        for method, f in fns.items():

            def make(dev, f=f, method=method):
                if method != "scan" and dev is runner.devs["cpu"]:
                    if work > PARALLEL_CPU_MAX_WORK:
                        return f"T*n = {work:.0e} > {PARALLEL_CPU_MAX_WORK:.0e} on the CPU"
                    if tier > 0 and runner.devs["gpu"] is not None:
                        return "CPU parallel forms timed at the first size only (4-100x slower than scan there)"
                args = [jax.device_put(x, dev) for x in (u, r, a, y0)]
                return lambda: f(*args)

            # the GPU scan is latency-bound (a fixed cost per step): predict from the same n, by T
            res = runner.case("play", case, method, work, "op-steps/s", make, ref_key=("play", case), pred=(n, float(T)))
            for dname, (row, _host) in res.items():
                if method == "scan":
                    scan_s[dname] = row["seconds"]
                elif dname in scan_s:
                    row["vs_scan"] = scan_s[dname] / row["seconds"]
                if dname == "gpu" and "cpu" in scan_s:
                    row["vs_cpu_scan"] = scan_s["cpu"] / row["seconds"]
        runner.refs.pop(("play", case), None)


def run_batch(runner: Runner, quick: bool, tier: int):
    import jax

    import smafl_jax as sj

    sz = SIZES[quick]
    T = sz["batch_T"]
    truth = sj.load_model(ROOT / "datasets" / "truth.json")
    for B in sz["batch_B"][tier]:
        work = float(B) * T
        need = 10 * 8 * B * T  # drive, thermal state, scaled input, output and scratch: ~10 (B, T) float64 buffers
        case = f"B={B} T={_fmt(T)}"
        U = _drives(B, T, seed=B)

        def make(dev, U=U):
            if need > MEM_CAP_BYTES:
                return f"~{need / 2**30:.1f} GiB > cap {MEM_CAP_BYTES / 2**30:.0f} GiB"
            m, x = _put(truth, dev), jax.device_put(U, dev)
            return lambda: sj.simulate_batch(m, x, DT)

        runner.case("batch", case, "simulate_batch", work, "record-steps/s", make)


def run_sweep(runner: Runner, quick: bool, tier: int):
    import jax.numpy as jnp
    import numpy as np

    import smafl_jax as sj

    sz = SIZES[quick]
    truth = sj.load_model(ROOT / "datasets" / "truth.json")
    ref = sj.sine_reference(sz["sweep_duration_s"], DT)
    n_steps = len(ref)
    for side in sz["sweep_side"][tier]:
        n_cfg = side * side
        grid = {"pid.kp": np.linspace(5, 60, side), "pid.ki": np.linspace(0, 40, side)}
        work = float(n_cfg) * n_steps
        case = f"{n_cfg} configs x {n_steps} steps"

        def make(dev, grid=grid):
            with on(dev):  # the loop's arrays are made on the device that runs the sweep
                loop = sj.ClosedLoop(
                    plant=truth,
                    pid=sj.PID(35.0, 20.0, 0.0),
                    reference=jnp.asarray(ref),
                    compensator=sj.IICompensator(truth, 10.0),
                )
            # shard=False: one device per run, even where several are visible
            return lambda: sj.sweep(loop, DT, grid, shard=False).metrics["e_mean_mm"]

        runner.case("sweep", case, "sweep", work, "loop-steps/s", make)


def run_posterior(runner: Runner, quick: bool, tier: int):
    import numpy as np

    import smafl_jax as sj

    sz = SIZES[quick]
    truth = sj.load_model(ROOT / "datasets" / "truth.json")
    rec = sj.load_record(ROOT / "datasets" / "main_loop.csv")
    posts = {}
    for nw in sz["walkers"][tier]:
        case = f"{nw} walkers x {len(rec)} samples"

        def make(dev, nw=nw):
            if dev not in posts:
                with on(dev):  # the data and model arrays of the density live on the device
                    posts[dev] = sj.Posterior(truth, rec, linear="sample")
            post = posts[dev]
            theta0 = np.asarray(post.theta0, dtype=np.float64)
            rng = np.random.default_rng(nw)
            thetas = theta0 + 1e-3 * np.maximum(np.abs(theta0), 1.0) * rng.standard_normal((nw, post.ndim))
            return lambda: post(thetas)

        runner.case("posterior", case, "log_prob batch", float(nw), "evals/s", make)


RUNNERS = {"play": run_play, "batch": run_batch, "sweep": run_sweep, "posterior": run_posterior}


# -- table ---------------------------------------------------------------------------------------


def _g(x, fmt=".3g"):
    return "-" if x is None else format(x, fmt)


def table(doc: dict) -> str:
    """Compact markdown: one line per (section, case, method), CPU and GPU side by side."""
    meta, rows = doc["meta"], doc["rows"]
    merged: dict = {}
    for r in rows:
        merged.setdefault((r["section"], r["case"], r["method"]), {})[r["device"]] = r
    lines = [
        f"GPU: {meta.get('gpu_name') or 'none'} | CPU: {meta.get('cpu')} | jax {meta.get('jax')} | "
        f"{meta.get('elapsed_s', 0):.0f} s | placement {meta.get('placement')} {meta.get('device_note') or ''}".rstrip(),
        "",
        "| section | case | method | unit | CPU s | GPU s | GPU/CPU | GPU vs CPU scan | vs scan (GPU) | compile CPU/GPU s "
        "| max abs diff | note |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for (sec, case, method), d in merged.items():
        c, g = d.get("cpu", {}), d.get("gpu", {})
        diff = g.get("max_abs_diff") if g else c.get("max_abs_diff")
        note = "; ".join(x for x in (c.get("note"), g.get("note")) if x)
        unit = (g or c).get("unit", "")
        lines.append(
            f"| {sec} | {case} | {method} | {unit} | {_g(c.get('seconds'), '.4g')} | {_g(g.get('seconds'), '.4g')} | "
            f"{_g(g.get('ratio'))} | {_g(g.get('vs_cpu_scan'))} | {_g(g.get('vs_scan'))} | {_g(c.get('compile_s'), '.2g')}/{_g(g.get('compile_s'), '.2g')} | "
            f"{_g(diff, '.1e')} | {note} |"
        )
    if meta.get("skipped"):
        lines.append("")
        lines.append(f"skipped for the budget: {len(meta['skipped'])} (" + "; ".join(meta["skipped"])[:600] + ")")
    return "\n".join(lines)


# -- main ----------------------------------------------------------------------------------------


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, type=Path, help="folder for results.json (created)")
    ap.add_argument("--quick", action="store_true", help="tiny sizes (a CPU smoke test)")
    ap.add_argument("--budget-s", type=float, default=330.0, help="stop starting cases past this wall time (s)")
    ap.add_argument("--only", default=",".join(SECTIONS), help=f"comma-separated sections of {SECTIONS}")
    ap.add_argument("--tiers", type=int, default=3, help="how many sizes per section (1-3)")
    ap.add_argument("--render", action="store_true", help="print the table of OUT/results.json and exit")
    ap.add_argument("--fake-accel", action="store_true", help="use a second host CPU device as the 'gpu' (tests placement)")
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    if a.render:
        path = a.out / "results.json"
        if not path.exists():
            print(f"no {path}")
            return 1
        print(table(json.loads(path.read_text())))
        return 0
    sections = [s.strip() for s in a.only.split(",") if s.strip()]
    unknown = set(sections) - set(SECTIONS)
    if unknown:
        ap.error(f"unknown sections {sorted(unknown)}; choose from {SECTIONS}")
    if a.fake_accel:
        os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=2").strip()
    sys.path.insert(0, str(ROOT))
    import jax

    import smafl_jax  # noqa: F401  (switches JAX to x64)

    jax.config.update("jax_enable_x64", True)
    budget = Budget(a.budget_s)
    devs, dnote = _devices(a.fake_accel)
    gpu = devs["gpu"]
    meta = {
        "quick": a.quick,
        "budget_s": a.budget_s,
        "jax": jax.__version__,
        "python": platform.python_version(),
        "cpu": f"{platform.processor() or platform.machine()} x{os.cpu_count()}",
        "cpu_device": str(devs["cpu"]),
        "gpu_device": None if gpu is None else str(gpu),
        "gpu_name": None if gpu is None else getattr(gpu, "device_kind", str(gpu)),
        "device_note": dnote,
        "x64": str(jax.numpy.zeros(()).dtype) == "float64",
    }
    progress(f"jax {jax.__version__}, backend {jax.default_backend()}, devices {jax.devices()}; cpu {devs['cpu']}, gpu {gpu}")
    if dnote:
        progress(dnote)
    meta["placement"] = _placement_check(devs)
    progress(f"placement check: {meta['placement']}")
    runner = Runner(a.out, devs, budget, meta)
    for tier in range(min(max(a.tiers, 1), 3)):
        # the largest sizes: cheap sections first, so the budget is not spent on the play bank alone
        order = sections if tier < 2 else sorted(sections, key=("posterior", "sweep", "batch", "play").index)
        for s in order:
            if budget.elapsed() > budget.limit:
                budget.skipped.append(f"{s} size {tier + 1}: not started (budget)")
                continue
            progress(f"== {s}, size {tier + 1}/3 ({budget.elapsed():.0f} s used)")
            try:
                RUNNERS[s](runner, a.quick, tier)
            except Exception as exc:  # a broken section must not lose the others
                msg = f"{type(exc).__name__}: {str(exc).splitlines()[0][:300] if str(exc) else ''}"
                progress(f"{s} size {tier + 1} FAILED: {msg}")
                runner.rows.append(dict(section=s, case=f"size {tier + 1}", method="-", device="-", seconds=None, note=msg))
            runner.save()
    runner.save()
    doc = json.loads((a.out / "results.json").read_text())
    print()
    print(table(doc), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
