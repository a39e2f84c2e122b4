"""`smafl diagnose A.csv B.csv` on pairs of independent records of one plant (issue 14 / 13): per record vs the set.

Each case is one plant of the independent effect generator (experiments/indep_effects.py on tests/indep_plant.py, plain
numpy, no smafl_jax): record A is the generator's own record of that truth and seed; record B is the same plant (same
structure, effect, start and noise) under another drive family.  Both go through the CLI in one call; the script
reports what each record's own diagnosis selected and what the set names (`AGREEMENT_RULE`).

Run:  python experiments/diagnose_several.py OUT_DIR none:1 none:2 creep:1 ...   (writes OUT_DIR/results.json)
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "experiments"))
import indep_effects as ie  # noqa: E402  (plain numpy)
import indep_plant as ip  # noqa: E402


def pair(folder: Path, truth: str, seed: int) -> list[Path]:
    """Two records of one plant: the generator's record, and the same plant under the next drive family."""
    path_a, case = ie.write_effect_record(folder, truth, seed)
    families = list(ip.FAMILIES)
    other = families[(families.index(case["drive"]) + 1) % len(families)]
    rec_b = ip.make_record(
        case["plant_seed"],
        effect=ie.CASES[truth][0],
        variant=case["variant"],
        drive=other,
        rate_hz=case["rate_hz"],
        minutes=case["minutes"],
        start=case["start"],
        noise=case["noise"],
    )
    path_b = ip.write_csv(folder / f"{truth}_s{seed}_b.csv", rec_b)
    return [path_a, path_b]


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    out = Path(args[0])
    out.mkdir(parents=True, exist_ok=True)
    results_path = out / "results.json"
    results = json.loads(results_path.read_text()) if results_path.exists() else {}
    for spec in args[1:]:
        truth, seed = spec.split(":")
        key = f"{truth}:{seed}"
        if key in results:
            continue
        folder = out / f"{truth}_s{seed}"
        folder.mkdir(exist_ok=True)
        paths = pair(folder, truth, int(seed))
        t0 = time.time()
        cmd = [sys.executable, "-m", "smafl_jax.cli", "diagnose", *map(str, paths), "--out", str(folder / "diag"), "--quiet"]
        done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
        if done.returncode != 0:
            results[key] = {"error": done.stderr[-2000:]}
        else:
            doc = json.loads((folder / "diag" / "diagnosis.json").read_text())
            results[key] = {
                "truth": truth,
                "per_record": [r["selected"] for r in doc["records"]],
                "set": doc["consistent"],
                "some_records": doc["some_records"],
                "x_noise": [[r["base_heldout_over_noise"], r["extended_heldout_over_noise"]] for r in doc["records"]],
                "seconds": time.time() - t0,
            }
        print(key, results[key], flush=True)
        tmp = results_path.with_suffix(".tmp")
        tmp.write_text(json.dumps(results, indent=1))
        tmp.replace(results_path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
