"""Session 27: fit_record on one thread with JAX's compile log and cache-miss explanations pickled (to find programs
compiled more than once with one signature).  python compile_log.py REC.csv OUT.pkl"""
import logging, re, sys, time, collections, pickle
import jax
jax.config.update("jax_log_compiles", True)
recs = []
class H(logging.Handler):
    def emit(self, r):
        recs.append((time.time(), r.name, r.getMessage()))
h = H(); h.setLevel(logging.DEBUG)
root = logging.getLogger("jax"); root.addHandler(h); root.setLevel(logging.DEBUG)
import smafl_jax as sj
from smafl_jax.report import _report_fit, fit_record
_report_fit.candidate_threads = lambda n: 1
t0 = time.time()
model, doc, _ = fit_record(sj.load_record(sys.argv[1]))
print("wall", time.time() - t0)
recs = [r for r in recs if r[1] in ("jax._src.interpreters.pxla", "jax._src.dispatch") or "Finished XLA" in r[2] or "cache miss" in r[2].lower() or "TRACING CACHE MISS" in r[2]]
pickle.dump(recs, open(sys.argv[2], "wb"))
