"""Session 34: training (and optionally leave-one-record-out) error per record of the several-records sets, with the
checkout ROOT's library (`fit_records`, `--model cascade` as the CLI).  Records: the CSVs written by probe.py
(/tmp/pm_SEED_SET/).

    python .notes/session34/memory/fit_sets.py ROOT OUT.json loro|none SEED[:SET] ...     (SET: mixed | wc | alike)
"""

import json
import os
import sys
import time
from pathlib import Path

root = sys.argv[1]
sys.path.insert(0, root)
sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "tests"))
import indep_plant  # noqa: E402
import numpy as np  # noqa: E402

import smafl_jax as sj  # noqa: E402

assert sj.__file__.startswith(root), sj.__file__
from smafl_jax.models._hysteresis import record_model  # noqa: E402

SETS = {
    "mixed": [("pwm", 25, 8, "cold"), ("multisine", 25, 8, "warm"), ("steps", 10, 12, "mid")],
    "wc": [("pwm", 25, 8, "cold"), ("multisine", 50, 5, "warm")],
    "alike": [("pwm", 25, 8, "cold"), ("multisine", 25, 8, "cold")],
}


def main():
    out, split = Path(sys.argv[2]), sys.argv[3]
    rows = json.loads(out.read_text()) if out.exists() else []
    done = {(r["seed"], r["set"]) for r in rows}
    for arg in sys.argv[4:]:
        seed, _, which = arg.partition(":")
        for name in [which] if which else ["mixed", "wc"]:
            seed = int(seed)
            if (seed, name) in done:
                continue
            d = Path(f"/tmp/pm_recs/{seed}_{name}")
            d.mkdir(parents=True, exist_ok=True)
            recs, noise = [], None
            for j, (drive, rate, minutes, start) in enumerate(SETS[name]):
                path = d / f"s{seed}_{j}_{drive}{rate}_{start}.csv"
                if not path.exists():
                    rec = indep_plant.make_record(seed, drive=drive, rate_hz=rate, minutes=minutes, start=start)
                    indep_plant.write_csv(path, rec)
                    (d / f"noise_{j}.txt").write_text(str(rec["noise_sd"]))
                noise = float((d / "noise_0.txt").read_text())
                recs.append(sj.load_record(path))
            t0 = time.perf_counter()
            _, doc, details = sj.fit_records(recs, model="cascade", split="auto" if split == "loro" else split)
            wall = time.perf_counter() - t0
            rm = details["record_model"]
            train = [float(np.sqrt(np.mean((np.asarray(record_model(rm, i).simulate(r.u, r.dt)) - r.y) ** 2))) / noise for i, r in enumerate(recs)]
            folds = (doc.get("validation") or {}).get("folds") or []
            row = {
                "seed": seed,
                "set": name,
                "train_x_noise": doc["metrics"]["train"]["rmse"] / noise,
                "train_per_record_x_noise": train,
                "loro_x_noise": doc["metrics"]["validation"]["rmse"] / noise if doc["metrics"]["validation"] else None,
                "loro_per_record_x_noise": [f["model"]["rmse"] / noise if f["model"] else None for f in folds],
                "memory": [p.get("memory") for p in doc.get("per_record_start") or []],
                "record_memory": getattr(rm, "record_memory", None) is not None,
                "tau_fit_s": 1.0 / float(rm.thermal.k1),
                "wall_s": wall,
            }
            rows.append(row)
            tmp = out.with_suffix(".tmp")
            tmp.write_text(json.dumps(rows, indent=1))
            os.replace(tmp, out)
            f = lambda xs: ", ".join("-" if v is None else f"{v:.2f}" for v in xs)
            print(f"seed {seed} {name}: train {row['train_x_noise']:.2f}x ({f(train)}), LORO "
                  f"{row['loro_x_noise'] or float('nan'):.2f}x ({f(row['loro_per_record_x_noise'])}), memory per record "
                  f"{row['record_memory']}, tau {row['tau_fit_s']:.1f} s, {wall:.0f} s", flush=True)


if __name__ == "__main__":
    main()
