import os, sys, time
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import smafl_jax as sj
from smafl_jax.report import fit_record
rec = sj.load_record("/tmp/s26/bench.csv")
for i in range(int(os.environ.get("N", "2"))):
    t0 = time.perf_counter(); m, doc, _ = fit_record(rec); print(i, round(time.perf_counter() - t0, 1), [(c["structure"], round(c["seconds"], 1)) for c in doc["settings"]["structure_choice"]["candidates"]], flush=True)
