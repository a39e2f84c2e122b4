"""Records at the brief's limits (5-100 Hz, 5-60 min): does every command finish, in what time and memory?

Each record comes from tests/indep_plant.py (plain numpy, no smafl_jax code) and is run through the command line as a
user would (`smafl fit REC --out ...`, then `smafl simulate` of the saved fit on the whole record), one process at a
time, with the process's peak resident memory (``ru_maxrss`` of the child) and wall time.  Optional: `smafl sample`
(a short chain) and `smafl diagnose` on the smaller records.  Session 32: the 60-min 100 Hz PWM record (360 000
samples) was killed by the kernel at > 22 GB before the Gaussian-Preisach relay step was checkpointed, then stopped on
a Cholesky error in the memory search.  Results go to experiments/results/long_records_<tag>.md (written atomically).

    python experiments/long_records.py [--only pwm100_60] [--sample] [--diagnose] [--no-figures] [--tag session32]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import indep_plant  # noqa: E402  (plain numpy; shares no code with smafl_jax)

#: name -> (seed, drive, rate Hz, minutes, start, orientation)
RECORDS = {
    "multisine5_5_length": (21, "multisine", 5, 5, "cold", "length"),
    "steps100_30": (22, "steps", 100, 30, "warm", None),
    "chirp50_60": (23, "chirp", 50, 60, "cold", None),
    "random10_60_length": (24, "random_levels", 10, 60, "cold", "length"),
    "triangle100_5": (25, "triangle", 100, 5, "warm", None),
    "pwm100_60": (7, "pwm", 100, 60, "cold", None),
}


def _run(args: list[str], log: Path) -> tuple[int, float, float]:
    """``(return code, wall s, peak GB)`` of one command-line call in a fresh process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    t0 = time.perf_counter()
    with open(log, "w") as fh:
        rc = subprocess.call([sys.executable, "-m", "smafl_jax.cli", *args], stdout=fh, stderr=subprocess.STDOUT, cwd=ROOT)
    wall = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    # ru_maxrss of the children is the largest of any child so far: report it only when this call raised it
    return rc, wall, (peak / 1e6 if peak > before else float("nan"))


def _line(path: Path, start: str) -> str:
    for ln in path.read_text(errors="replace").splitlines():
        if ln.startswith(start):
            return ln
    return ""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", default=list(RECORDS), choices=list(RECORDS))
    ap.add_argument("--sample", action="store_true", help="also `smafl sample --steps 60` of each fit")
    ap.add_argument("--diagnose", action="store_true", help="also `smafl diagnose` of records up to 30 000 samples")
    ap.add_argument("--tag", default="run")
    ap.add_argument("--no-figures", action="store_true", help="pass --no-figures to `smafl fit`")
    a = ap.parse_args()
    env_note = f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}"
    rows = ["| record | samples | command | rc | wall s | peak GB | result |", "|---|---|---|---|---|---|---|"]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name in a.only:
            seed, drive, rate, minutes, start, orientation = RECORDS[name]
            rec = indep_plant.make_record(seed, drive=drive, rate_hz=rate, minutes=minutes, start=start, orientation=orientation)
            csv = indep_plant.write_csv(tmp / f"{name}.csv", rec)
            col = csv.read_text().splitlines()[0].split(",")[-1]
            n = rec["meta"]["n"]
            fig = ["--no-figures"] if a.no_figures else []
            calls = [("fit", ["fit", str(csv), *fig, "--out", str(tmp / f"fit_{name}")])]
            calls.append(
                ("simulate", ["simulate", str(tmp / f"fit_{name}" / "fit.json"), str(csv), "--measured", col, "--out", str(tmp / f"sim_{name}")])
            )  # fmt: skip
            if a.sample:
                calls.append(
                    ("sample", ["sample", "--fit", str(tmp / f"fit_{name}" / "fit.json"), str(csv), "--out", str(tmp / f"smp_{name}"),
                                "--steps", "60", "--no-progress"])
                )  # fmt: skip
            if a.diagnose and n <= 30_000:
                calls.append(("diagnose", ["diagnose", str(csv), "--out", str(tmp / f"dia_{name}")]))
            for what, args in calls:
                log = tmp / f"{what}_{name}.log"
                rc, wall, peak = _run(args, log)
                result = {
                    "fit": lambda: _line(log, "train rmse"),
                    "simulate": lambda: _line(log, "against measured"),
                    "sample": lambda: _line(log, "held-out points"),
                    "diagnose": lambda: _line(log, "selected:"),
                }[what]()
                if rc != 0:
                    result = " / ".join(log.read_text(errors="replace").strip().splitlines()[-2:])
                shown = f"{peak:.1f}" if peak == peak else "below an earlier call's"  # nan: not raised by this call
                row = f"| {name} | {n} | {what} | {rc} | {wall:.0f} | {shown} | {result[:160]} |"
                print(row, flush=True)
                rows.append(row)
    out = ROOT / "experiments" / "results" / f"long_records_{a.tag}.md"
    text = "\n".join([f"# Long records ({a.tag}; {env_note}; `python experiments/long_records.py`)", "", *rows, ""])
    if out.exists():
        print(f"note: replacing {out}")
    tmp_out = out.with_suffix(".md.tmp")
    tmp_out.write_text(text)
    os.replace(tmp_out, out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
