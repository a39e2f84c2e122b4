"""Is the thermal model the bottleneck on plant B?  The same plant-B draws with `linear_thermal=True` (no radiation,
constant resistance: exactly the toolkit's first-order lag in V^2) fitted with the CLI like class_choice_confirm
(first 70 %, default options of one class), scored on the last 30 % and on the first 70 % (RMSE / noise SD).
Compare with the nonlinear twins' fits in /tmp/cf_work (session 22, same seeds/cells).
    python thermal_ablation.py CLASS SEEDS RATES OUT.jsonl     e.g.  G "6 7" "5 25" out.jsonl"""
import json, os, subprocess, sys, time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT / "experiments"), str(ROOT / "tests")]
import fit_plant_b as fb
import indep_plant_b as pb

CLS = {"E": ["--model", "cascade", "--thresholds", "--tilts"], "P": ["--model", "cascade-preisach"],
       "G": ["--model", "cascade-preisach-gauss"], "auto": []}
cls, seeds, rates, out = sys.argv[1], [int(s) for s in sys.argv[2].split()], [float(r) for r in sys.argv[3].split()], sys.argv[4]
WORK = Path("/tmp/s23_lin")
cells = [c for c in fb.grid(seeds, 10.0) if c["rate_hz"] in rates]


def job(c):
    name = fb.name_of(c)
    d = WORK / name
    d.mkdir(parents=True, exist_ok=True)
    r = pb.make_record(c["seed"], **{k: v for k, v in c.items() if k != "seed"}, linear_thermal=True)
    h0 = r["heldout_start"]
    pb.write_csv(d / "first70.csv", r, stop=h0)
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    t0 = time.time()
    p = subprocess.run([sys.executable, "-m", "smafl_jax", "fit", str(d / "first70.csv"), "--out", str(d / f"fit_{cls}"),
                        "--no-figures", *CLS[cls]], env=env, capture_output=True, text=True)
    row = {"name": name, "cls": cls, "truth": r["truth"]["hysteresis"]["class"], "rc": p.returncode, "wall": time.time() - t0}
    if p.returncode == 0:
        import smafl_jax as sj
        m = sj.load_model(d / f"fit_{cls}" / "fit.json")
        yh = np.asarray(sj.simulate(m, r["voltage"], 1.0 / c["rate_hz"]))
        e = yh - r["output"]
        row["held_x"] = float(np.sqrt(np.mean(e[h0:] ** 2)) / r["noise_sd"])
        row["train_x"] = float(np.sqrt(np.mean(e[:h0] ** 2)) / r["noise_sd"])
        row["T_inside"] = r["truth"]["heldout_T_inside"]
    else:
        row["err"] = p.stderr[-300:]
    with open(out, "a") as f:
        f.write(json.dumps(row) + "\n")
    print(json.dumps(row), flush=True)


with ThreadPoolExecutor(int(os.environ.get("WORKERS", "2"))) as ex:
    list(ex.map(job, cells))
