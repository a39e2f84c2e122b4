"""Do two equally good fits (rule vs fitted operator memory) disagree on a drive sweep where one of them fails held out?

python .notes/session48/memory_spread.py ROOT OUT.jsonl SEED CELL...   (CELL: a key of tests/indep_plant.MATRIX_CELLS)
Each record (10 min): fit_record on the first 70 % with memory "rule" and with memory "fitted"; held-out RMSE of each
over the noise SD; their disagreement (RMS over the noise SD) on (a) the held-out part and (b) a probe: the training
drive followed by three slow triangle sweeps over the trained drive range (10 min each), scored on the sweeps only.
"""

import json
import sys
from pathlib import Path

import numpy as np

root, out, seed, cells = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4:]
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
sys.path.insert(0, str(Path(root).resolve()))
import indep_plant as ip  # noqa: E402

import smafl_jax as sj  # noqa: E402
from smafl_jax.report import fit_record  # noqa: E402

for cell in cells:
    r = ip.make_record(seed, minutes=10.0, **ip.MATRIX_CELLS[cell])
    h0, sd, dt = r["heldout_start"], r["noise_sd"], r["dt"]
    p = f"/tmp/s48/spread_{seed}_{cell.replace(' ', '').replace(',', '_')}.csv"
    ip.write_csv(p, r)
    rec = sj.load_record(p)
    p70 = p.replace(".csv", "_70.csv")
    sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
    lo, hi = float(np.min(rec.u[:h0])), float(np.max(rec.u[:h0]))
    n_sw = int(round(600.0 / dt))
    tri = lo + (hi - lo) * (1.0 - np.abs(2.0 * (np.arange(n_sw) / n_sw) - 1.0))
    probe = np.concatenate([rec.u[:h0], np.tile(tri, 3)])
    preds, held = {}, {}
    for mem in ("rule", "fitted"):
        model, doc, _ = fit_record(sj.load_record(p70), memory=mem)
        yh = np.asarray(sj.simulate(model, rec.u, dt))
        held[mem] = float(np.sqrt(np.mean((yh[h0:] - rec.y[h0:]) ** 2)) / sd)
        preds[mem] = (yh, np.asarray(sj.simulate(model, probe, dt)))
    d_held = float(np.sqrt(np.mean((preds["rule"][0][h0:] - preds["fitted"][0][h0:]) ** 2)) / sd)
    d_probe = float(np.sqrt(np.mean((preds["rule"][1][h0:] - preds["fitted"][1][h0:]) ** 2)) / sd)
    d_train = float(np.sqrt(np.mean((preds["rule"][0][:h0] - preds["fitted"][0][:h0]) ** 2)) / sd)
    row = dict(seed=seed, cell=cell, held=held, disagree_train=d_train, disagree_held=d_held, disagree_probe=d_probe)
    print(json.dumps(row), flush=True)
    with open(out, "a") as f:
        f.write(json.dumps(row) + "\n")
