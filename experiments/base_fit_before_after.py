"""Issue 18 before/after: default `smafl fit` (fit_record defaults) on independent records, one code root.

Records come from tests/indep_plant.py (plain numpy, no smafl_jax import; random thresholds, tilts, operator
memory, thermal scheme, sensor).  Each record is fitted on its first 70 % and scored on the last 30 %
(RMSE / noise SD).  CODE_ROOT is the checkout whose smafl_jax is imported, so an older commit
(`git archive COMMIT | tar -x -C /tmp/old`) and this one run the same records side by side:

    python experiments/base_fit_before_after.py /tmp/old   /tmp/old.json  10 7 11
    python experiments/base_fit_before_after.py .          /tmp/new.json  10 7 11
    python experiments/base_fit_before_after.py --table /tmp/old.json /tmp/new.json

SMAFL_FIT_OPTS='{"max_steps": 40}' (JSON) passes keyword options to `fit_record`, to compare settings of one tree.
SMAFL_CELLS='PWM' keeps only the cells whose name contains that text; SMAFL_CELLS_JSON='{"PWM 100 Hz": {"drive": "pwm",
"rate_hz": 100, "start": "cold"}}' replaces the cells (keywords of tests/indep_plant.make_record).
"""

import json
import os
import sys
import time
from pathlib import Path

import numpy as np

if len(sys.argv) > 1 and sys.argv[1] == "--table":
    runs = [json.load(open(p)) for p in sys.argv[2:]]
    print("| record | seed | " + " | ".join(f"{Path(p).stem} train | {Path(p).stem} held-out | s" for p in sys.argv[2:]) + " |")
    print("| --- | --- | " + " | ".join("--- | --- | ---" for _ in runs) + " |")
    for rows in zip(*runs):
        cells = " | ".join(f"{r['train']:.2f}x | {r['held']:.2f}x | {r['seconds']:.0f}" for r in rows)
        print(f"| {rows[0]['cell']} | {rows[0]['seed']} | {cells} |")
    for p, rows in zip(sys.argv[2:], runs):
        h = np.array([r["held"] for r in rows])
        print(
            f"\n- {Path(p).stem}: median held-out {np.median(h):.2f}x noise, within 1.5x: {int(np.sum(h <= 1.5))}/{len(h)}, "
            f"within 3x: {int(np.sum(h <= 3))}/{len(h)}"
        )
    sys.exit(0)
root = sys.argv[1]
out = sys.argv[2]
minutes = float(sys.argv[3])
seeds = [int(s) for s in sys.argv[4:]]
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
sys.path.insert(0, str(Path(root).resolve()))
import indep_plant as ip  # noqa: E402

import smafl_jax as sj  # noqa: E402
from smafl_jax.report import fit_record  # noqa: E402

CELLS = dict(ip.MATRIX_CELLS)
OPTS = json.loads(os.environ.get("SMAFL_FIT_OPTS", "{}"))
CELLS = json.loads(os.environ["SMAFL_CELLS_JSON"]) if "SMAFL_CELLS_JSON" in os.environ else CELLS
CELLS = {k: v for k, v in CELLS.items() if os.environ.get("SMAFL_CELLS", "") in k}
rows = []
for seed in seeds:
    for name, kw in CELLS.items():
        r = ip.make_record(seed, minutes=minutes, **kw)
        h0 = r["heldout_start"]
        sd = r["noise_sd"]
        tag = f"{root.strip('/').replace('/', '_')}_{seed}_{kw['drive']}_{kw['start']}_{kw.get('orientation', 'd')}"
        Path("/tmp/smafl_before_after").mkdir(exist_ok=True)
        p = f"/tmp/smafl_before_after/m_{tag}.csv"
        ip.write_csv(p, r)
        rec = sj.load_record(p)
        p70 = f"/tmp/smafl_before_after/m70_{tag}.csv"
        sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
        t0 = time.time()
        model, doc, _ = fit_record(sj.load_record(p70), **OPTS)
        sec = time.time() - t0
        yh = np.asarray(sj.simulate(model, rec.u, rec.dt))
        e = yh - rec.y
        screening = doc["settings"].get("start_screening") or []
        row = dict(
            cell=name,
            seed=seed,
            n=len(rec),
            train=float(np.sqrt(np.mean(e[:h0] ** 2)) / sd),
            held=float(np.sqrt(np.mean(e[h0:] ** 2)) / sd),
            # the fit's own validation block (the last part of the 70 %), what `--model auto` chooses on
            val=(doc["metrics"].get("validation") or {}).get("rmse", np.nan) / sd,
            candidates={  # --model auto: each candidate's validation RMSE over the noise SD
                c["structure"]: (c["validation"] or {}).get("rmse", np.nan) / sd
                for c in (doc["settings"].get("structure_choice") or {}).get("candidates", [])
            },
            candidates_train={  # each candidate's split-training RMSE over the noise SD (the class-choice rule reads it)
                c["structure"]: c["train_rmse"] / sd
                for c in (doc["settings"].get("structure_choice") or {}).get("candidates", [])
            },
            # the split fit's operator-memory choice (rule vs fitted, each with its validation RMSE), as fit.json says it
            memory_choice=[n for n in doc.get("notes", []) if "operator memory at t = 0" in n],
            # how far the rule- and fitted-memory split fits part on sweeps of the trained range (session 48)
            memory_spread=doc["settings"].get("memory_spread"),
            seconds=sec,
            chosen=(doc["settings"].get("structure_choice") or {}).get("chosen", doc["settings"].get("structure")),
            k1_true=r["truth"]["thermal"]["k1"],
            k1=float(getattr(getattr(model, "thermal", None), "k1", np.nan)),
            memory=r["truth"]["hysteresis"]["memory"]["kind"],
            sensor=r["truth"]["sensor"]["orientation"],
            fit_orientation=getattr(getattr(model, "hysteresis", None), "orientation", None),
            orientation_ambiguous=any(n.startswith("output orientation") for n in doc.get("notes", [])),
            profiled_loss_by_sign={
                str(sign): min(
                    (row["loss"] for row in screening if row["orientation"] == sign and row.get("loss") is not None), default=None
                )
                for sign in (1, -1)
            },
            opts=OPTS,
        )
        rows.append(row)
        print(json.dumps(row), flush=True)
        json.dump(rows, open(out, "w"), indent=1)
