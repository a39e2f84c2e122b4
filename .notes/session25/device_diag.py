"""Session 25 device run: blind diagnoses of independent-plant effect records, one process per record, on the lent
machine's CPU cores (JAX on the CPU: a sequential scan is slower on the GPU).  Slots of 2 cores each (taskset), a
deadline after which running jobs are stopped; each finished record leaves its own JSON under $OUT.

    python .notes/session25/device_diag.py OUT DEADLINE_S SLOTS "truth:seed" ...
"""
import os
import subprocess
import sys
import time
from pathlib import Path

out, deadline, slots = Path(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])
jobs = [j.split(":") for j in sys.argv[4:]]
out.mkdir(parents=True, exist_ok=True)
root = Path(__file__).resolve().parents[2]
t0 = time.time()
free = list(range(slots))
running = {}
env = {**os.environ, "JAX_PLATFORMS": "cpu", "OPENBLAS_NUM_THREADS": "1", "PYTHONUNBUFFERED": "1"}
while jobs or running:
    while jobs and free:
        truth, seed = jobs.pop(0)
        s = free.pop(0)
        cpus = f"{2 * s},{2 * s + 1}"
        tag = f"{truth}_s{seed}"
        cmd = ["taskset", "-c", cpus, sys.executable, str(root / "experiments" / "diagnose_independent.py"), "--seed", seed,
               "--truths", truth, "--n-null", "8", "--out", str(out / tag)]
        log = open(out / f"{tag}.log", "w")
        running[tag] = (subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env, cwd=root), s, time.time())
        print(f"{time.time() - t0:6.0f} s start {tag} on cpus {cpus}", flush=True)
    time.sleep(2)
    for tag, (p, s, ts) in list(running.items()):
        if p.poll() is not None:
            print(f"{time.time() - t0:6.0f} s done {tag} rc {p.returncode} in {time.time() - ts:.0f} s", flush=True)
            free.append(s)
            del running[tag]
    if time.time() - t0 > deadline:
        for tag, (p, s, ts) in running.items():
            p.kill()
            print(f"{time.time() - t0:6.0f} s killed {tag} after {time.time() - ts:.0f} s", flush=True)
        print("not started:", jobs, flush=True)
        break
