"""Default `smafl fit` wall time on a 30 000-sample record (issue 18: under 60 s on 2 cores).

One clean record of 20 minutes at 25 Hz from the independent numpy plant (tests/indep_plant.py, PWM
drive, cold start; quick: 5 minutes), fitted with every default of `fit_record` (= `smafl fit REC`:
structure, start screening, joint (k1, u0) search, fitted operator memory, split refinement, whole-record
refit), in a fresh process state (JIT compilation included, as a user pays it).  Side by side, in the same
process on the same record: the profiled start alone (``max_steps=0``: screening and variable projection,
no joint refinement), so the row shows what the gradient refinement costs.
Ratio = ours seconds / profiled-only seconds.  Other 30 000-sample records: ``--drive multisine --rate 100``
(the duration follows from the rate), one process per record so each pays its own compilation.

    python -m benchmarks.bench_default_fit [--quick] [--drive pwm|multisine|staircase|steps|chirp|triangle] [--rate HZ]
        [--threads N] [--solver lm|varpro|...] [--batch]

``--threads N``: at most N of ``--model auto``'s candidate classes at once (default: one per core); ``--threads 1``
in another process is the one-after-another baseline of the threaded fit.  ``--solver S``: the default fit with another
joint-refinement solver (`smafl fit --solver`); run once with each in separate processes for the ratio.

``--batch``: what a batch script pays per record after its first.  The benchmark record is fitted, then another record
of the same length (another seed, multisine drive) in the same process; row: second record's seconds / first record's
seconds.  The second reuses the compiled programs of the first (JAX's in-memory cache) wherever their shapes agree.

JIT compilation is always paid here: `fit_record` does not turn on the on-disk cache of compiled programs that the
`smafl` command line uses (`SMAFL_COMPILE_CACHE`; session 26: the CLI on this record 96.6 s with an empty cache, 64.2 s
warm).  ``JAX_COMPILATION_CACHE_DIR=DIR`` in the environment measures the warm case.  The row also gives each fit's
process CPU seconds (``cpu_seconds``).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

try:
    from ._common import progress, row
except ImportError:  # run as a script
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from benchmarks._common import progress, row

ROOT = Path(__file__).resolve().parents[1]
RATIO_MEANING = "default fit seconds / profiled-start-only seconds (what the joint refinement costs)"


def run(quick=False, drive="pwm", rate_hz=25, threads=None, solver=None, batch=False):
    sys.path.insert(0, str(ROOT / "tests"))
    import indep_plant

    import smafl_jax as sj
    from smafl_jax.report import (
        _report_fit,  # private: caps the candidate threads for the baseline
        fit_record,
    )

    if threads is not None:
        default = _report_fit.candidate_threads
        _report_fit.candidate_threads = lambda n: min(default(n), int(threads))

    minutes = (5.0 if quick else 20.0) * 25 / rate_hz  # 30 000 samples (quick: 7 500)
    r = indep_plant.make_record(7, drive=drive, rate_hz=rate_hz, minutes=minutes, start="cold")
    if batch:
        return [_batch_row(sj, fit_record, indep_plant, r, minutes, rate_hz, drive)]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "rec.csv"
        indep_plant.write_csv(path, r)
        rec = sj.load_record(path)
        seconds, cpu = {}, {}
        default = {} if solver is None else {"solver": solver}
        for label, opts in (("default", default), ("profiled only", {"max_steps": 0})):
            progress(f"default_fit: {label} on {len(rec)} samples")
            t0, c0 = time.perf_counter(), time.process_time()
            _, doc, _ = fit_record(rec, **opts)
            seconds[label], cpu[label] = time.perf_counter() - t0, time.process_time() - c0
            progress(
                f"default_fit: {label}: {seconds[label]:.1f} s ({cpu[label]:.1f} s of CPU), "
                f"train RMSE {doc['metrics']['train']['rmse']:.4g}"
            )
    return [
        row(
            f"default smafl fit, {len(rec)} samples (goal < 60 s)"
            + (f", at most {threads} candidate threads" if threads else "")
            + (f", solver {solver}" if solver else ""),
            seconds["default"],
            seconds["profiled only"],
            "s",
            note=f"independent {drive} record, {minutes:g} min at {rate_hz:g} Hz, cold start; JIT compilation included",
            n_samples=len(rec),
            # CPU seconds of the process (every thread): on a shared machine whose speed drifts, the same code's wall
            # time moved by 25 % within an hour (session 53) while its work did not; this separates the two
            cpu_seconds={k: round(v, 2) for k, v in cpu.items()},
        )
    ]


def _batch_row(sj, fit_record, indep_plant, first, minutes, rate_hz, drive):
    """The benchmark record, then another record of the same length in the same process (``--batch``)."""
    second = indep_plant.make_record(11, drive="multisine", rate_hz=rate_hz, minutes=minutes, start="cold")
    seconds, cpu = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for i, r in enumerate((first, second)):
            path = Path(tmp) / f"rec{i}.csv"
            indep_plant.write_csv(path, r)
            rec = sj.load_record(path)
            t0, c0 = time.perf_counter(), time.process_time()
            _, doc, _ = fit_record(rec)
            seconds.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
            progress(
                f"default_fit --batch: record {i + 1}: {seconds[-1]:.1f} s ({cpu[-1]:.1f} s of CPU), chosen {doc['settings']['structure_choice']['chosen']}"
            )
    return row(
        f"default smafl fit in a batch: a second {len(rec)}-sample record in the same process",
        seconds[1],
        seconds[0],
        "s",
        note=f"second record (multisine, seed 11) after the benchmark record ({drive}, seed 7); ratio = second / first",
        n_samples=len(rec),
        cpu_seconds={"first": round(cpu[0], 2), "second": round(cpu[1], 2)},
    )


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--drive", default="pwm")
    ap.add_argument("--rate", type=float, default=25.0)
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--solver", default=None)
    ap.add_argument("--batch", action="store_true", help="a second record in the same process (what a batch script pays)")
    a = ap.parse_args()
    for r_ in run(quick=a.quick, drive=a.drive, rate_hz=a.rate, threads=a.threads, solver=a.solver, batch=a.batch):
        print(r_)
