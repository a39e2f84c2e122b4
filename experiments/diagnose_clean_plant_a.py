"""`smafl diagnose` with its defaults on clean records of the independent plant A (issue 13: clean -> none).

The blind benchmark (`diagnose_independent.py`) keeps its records short (2000-4000 samples); the records here are
what issue 18's matrix draws: 10 minutes, a random drive family, sample rate 5-100 Hz, start (cold / warm / mid) and
sensor orientation (tests/indep_plant.py, plain numpy, no smafl_jax), and no effect at all.  Each record is written as
CSV and diagnosed by the CLI exactly as a user runs it; the table gives the base's training / held-out RMSE over the
plant's true noise SD, every effect the calibrated gates accepted, what was named, the
reference fit where one ran, and the time.

    python experiments/diagnose_clean_plant_a.py --seeds 301 302 --out /tmp/clean_a     # ~4-20 min per record
    python experiments/diagnose_clean_plant_a.py --out /tmp/clean_a --table             # the table of a finished run
    python experiments/diagnose_clean_plant_a.py --seeds 309 --split auto --out /tmp/clean_auto   # another split rule
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
import indep_plant as ip  # noqa: E402  (plain numpy; shares no code with smafl_jax)

MINUTES = 10.0


def run(seed: int, out: Path, split: str | None = None) -> None:
    csv = out / f"a{seed}.csv"
    if not csv.exists():
        ip.write_csv(csv, ip.make_record(seed, minutes=MINUTES))
    folder = out / f"out{seed}"
    if (folder / "diagnosis.json").exists():
        print(f"a{seed}: {folder} exists; not rerun", flush=True)
        return
    cmd = [sys.executable, "-m", "smafl_jax", "diagnose", str(csv), "--out", str(folder), "--quiet"]
    cmd += [] if split is None else ["--split", split]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    with open(out / f"a{seed}.log", "w") as log:
        subprocess.run(cmd, check=True, stdout=log, stderr=subprocess.STDOUT, env=env)


def table(out: Path) -> list[str]:
    rows = [
        "| record | drive | rate (Hz) | samples | start | sensor | base train / held-out (x noise) | gates accepted | named | "
        "reference (x noise) | s |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for f in sorted(out.glob("out*/diagnosis.json"), key=lambda p: int(p.parent.name[3:])):
        seed = int(f.parent.name[3:])
        tr = json.loads((out / f"a{seed}.truth.json").read_text())
        d = json.loads(f.read_text())
        sd, m, b = tr["noise_sd"], tr["meta"], d["base"]
        gates = [c["name"] for c in d["candidates"] if (c.get("calibration") or {}).get("accepted")]
        ref = (b.get("reference_fit") or {}).get("heldout_rmse")
        rows.append(
            f"| a{seed} | {m['drive']} | {m['rate_hz']:.1f} | {m['n']} | {tr['truth']['thermal']['start']} | "
            f"{tr['truth']['sensor']['orientation']} | {b['train_rmse'] / sd:.2f} / {b['heldout_rmse'] / sd:.2f} | "
            f"{', '.join(gates) or '-'} | {', '.join(d['selected']) or 'none'} | "
            f"{'-' if ref is None else format(ref / sd, '.2f')} | {d['seconds']:.0f} |"
        )
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="*", default=[])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--table", action="store_true", help="only print the table of the records diagnosed in --out")
    ap.add_argument("--split", choices=("time", "interleaved", "auto"), help="passed to smafl diagnose (default: its own)")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    if not args.table:
        for s in args.seeds:
            run(s, args.out, args.split)
    print("\n".join(table(args.out)))


if __name__ == "__main__":
    main()
