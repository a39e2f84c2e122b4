"""Probe: threshold spacing of the EUPI grid on the random-cell panel (one-mode cascade on each cell's first 70 %).

python .notes/session59/grid_panel.py OUT.jsonl VARIANT[,VARIANT] SEED...
VARIANT: default (i / 2n), geo (0.02 .. 0.5 geometric), quad (0.5 (i/n)^2), octave (asymmetric 0.5 / 2^(n-i)).
"""
import glob, json, sys, time
import numpy as np
import smafl_jax as sj
import smafl_jax.models._eupi as E
from smafl_jax.report import fit_record

D = "/tmp/smafl_before_after"
orig = E.threshold_grid
GRIDS = {
    "default": orig,
    "geo": lambda n: np.full(int(n), 0.25) if int(n) <= 1 else 0.5 * 0.04 ** ((int(n) - 1 - np.arange(int(n))) / (int(n) - 1)),
    # probe only: default grid sizes (8 symmetric, 4 asymmetric) -> uniform symmetric, geometric asymmetric thresholds
    "mixed": lambda n: orig(n) if int(n) == 8 else 0.5 * 0.04 ** ((int(n) - 1 - np.arange(int(n))) / (int(n) - 1)),
    # session 60: asymmetric thresholds an octave apart, 0.5 / 2^(n - i) (n = 4: 0.0625 0.125 0.25 0.5; n = 2 as uniform)
    "octave": lambda n: orig(n) if int(n) == 8 else 0.5 / 2.0 ** (int(n) - np.arange(1, int(n) + 1)),
    # session 60: six unparallel thresholds an octave apart (1/64 .. 0.5), a superset of the uniform 4-grid's 0.125 0.25 0.5
    "oct6": lambda n: orig(n) if int(n) == 8 else 0.5 / 2.0 ** (int(n) - np.arange(1, int(n) + 1)),
    "oct5": lambda n: orig(n) if int(n) == 8 else 0.5 / 2.0 ** (int(n) - np.arange(1, int(n) + 1)),  # 1/32 .. 0.5
    "quad": lambda n: 0.5 * (np.arange(1, int(n) + 1) / max(int(n), 1)) ** 2,
}
out, variants, seeds = sys.argv[1], sys.argv[2].split(","), sys.argv[3:]
for s in seeds:
    full = glob.glob(f"{D}/m_work_main_{s}_*.csv")[0]
    part = full.replace("/m_", "/m70_")
    truth = json.load(open(full.replace(".csv", ".truth.json")))
    rec, p70 = sj.load_record(full), sj.load_record(part)
    for v in variants:
        E.threshold_grid = GRIDS[v]
        t0 = time.time()
        extra = {"grid": {"n_asym": {"oct6": 6, "oct5": 5}[v]}} if v in ("oct6", "oct5") else {}
        m, doc, _ = fit_record(p70, model="cascade", slow_mode="off", **extra)
        yh = np.asarray(sj.simulate(m, rec.u, rec.dt))
        e = yh - rec.y; h0 = truth["heldout_start"]; sd = truth["noise_sd"]
        row = dict(seed=int(s), cell=full.split("main_")[1][:-4], variant=v,
                   train=float(np.sqrt(np.mean(e[:h0] ** 2)) / sd), held=float(np.sqrt(np.mean(e[h0:] ** 2)) / sd),
                   val=(doc["metrics"].get("validation") or {}).get("rmse", np.nan) / sd, seconds=time.time() - t0)
        print(json.dumps(row), flush=True)
        with open(out, "a") as f:
            f.write(json.dumps(row) + "\n")
