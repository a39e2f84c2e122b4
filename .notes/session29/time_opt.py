"""Session 29: cold fit_record of REC on one thread, wall time, XLA compile seconds and the fit's metrics (to compare
XLA flags).  XLA_FLAGS=... python time_opt.py REC"""
import logging, re, sys, time
import jax
jax.config.update("jax_log_compiles", True)
tot = [0.0, 0]
class H(logging.Handler):
    def emit(self, r):
        m = re.search(r"Finished XLA compilation of .*? in ([0-9.e-]+) sec", r.getMessage())
        if m:
            tot[0] += float(m.group(1)); tot[1] += 1
h = H(); h.setLevel(logging.DEBUG)
lg = logging.getLogger("jax"); lg.addHandler(h); lg.setLevel(logging.DEBUG)
import smafl_jax as sj
from smafl_jax.report import _report_fit, fit_record  # private: one thread, to compare flags on one core
_report_fit.candidate_threads = lambda n: 1
t0 = time.time()
model, doc, _ = fit_record(sj.load_record(sys.argv[1]))
m = doc["metrics"]
print("wall %.1f xla %.1f s in %d programs" % (time.time() - t0, tot[0], tot[1]), "train", m["train"]["rmse"], "val", m["validation"]["rmse"], "whole", m.get("whole_record", {}).get("rmse"), "kept", type(model).__name__)
