"""Run fit_record on the 70 % part of a random cell with progress, print the start-screening lines, exit once the
first cascade's hysteresis input is chosen (session 49 probe)."""
import json, logging, os, subprocess, sys
from pathlib import Path
import numpy as np
seed = int(sys.argv[1])
sys.path.insert(0, "/work/main/tests")
import indep_plant as ip
import smafl_jax as sj
from smafl_jax.report import fit_record
from smafl_jax._progress import LOGGER
line = subprocess.check_output([sys.executable, "/work/main/.notes/session48/random_cells.py", str(seed)], text=True).strip()
minutes, cell = float(line.split("\t")[1]), json.loads(line.split("\t")[2])
kw = next(iter(cell.values()))
r = ip.make_record(seed, minutes=minutes, **kw)
h0 = r["heldout_start"]
p = f"/tmp/s49/scr/rec_{seed}.csv"
ip.write_csv(p, r)
rec = sj.load_record(p)
p70 = f"/tmp/s49/scr/rec70_{seed}.csv"
sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
truth = r["truth"]["hysteresis"]["input"]
class H(logging.Handler):
    def emit(self, rec_):
        m = rec_.getMessage()
        if "start screening" in m or "chosen on" in m:
            print(seed, truth, m, flush=True)
        if "hysteresis input and memory rule chosen" in m:
            os._exit(0)
LOGGER.addHandler(H()); LOGGER.setLevel(logging.INFO)
fit_record(sj.load_record(p70), progress=True)
