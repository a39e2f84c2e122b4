"""Benchmark-record default fit in a fresh process (session 24): python time_auto.py CODE_ROOT; env THREADS=N caps the
candidate threads, ORDER=registry submits in registry order, EARLY=off (a variant not kept), DUMP=FILE writes model + metrics."""
import sys, time, json, tempfile, os
root = sys.argv[1]
sys.path[:0] = [root, root + "/tests"]
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import indep_plant
import smafl_jax as sj
from smafl_jax.report import fit_record
if os.environ.get("THREADS"):
    from smafl_jax.report import _report_fit
    _report_fit.candidate_threads = lambda n: min(n, int(os.environ["THREADS"]))
if os.environ.get("ORDER") == "registry":
    from smafl_jax.report import _report_fit
    _report_fit._submit_longest_first = lambda pool, job, names, first=0: [pool.submit(job, first + i, n) for i, n in enumerate(tuple(names))]
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
with tempfile.TemporaryDirectory() as tmp:
    p = os.path.join(tmp, "rec.csv"); indep_plant.write_csv(p, r); rec = sj.load_record(p)
    t0 = time.perf_counter()
    m, doc, _ = fit_record(rec)
    wall = time.perf_counter() - t0
sc = doc["settings"].get("structure_choice", {})
if os.environ.get("EARLY") == "off":
    from smafl_jax.report import _report_fit
    _report_fit._finish_early = lambda *a, **k: None
if os.environ.get("DUMP"):
    json.dump({"model": sj.model_to_dict(m), "metrics": doc["metrics"]}, open(os.environ["DUMP"], "w"), sort_keys=True, default=str)
print(json.dumps({"root": root, "threads": os.environ.get("THREADS"), "wall": wall, "chosen": sc.get("chosen"),
                  "cands": [(c["structure"], round(c["seconds"], 1), c["validation"]) for c in sc.get("candidates", [])],
                  "train": doc["metrics"]["train"]["rmse"]}))
