"""Session 27: one cold fit_record of a record with the code of ROOT (a git worktree), with the number of XLA
compilations and their seconds (JAX's compile log).  OPENBLAS_NUM_THREADS=1 SMAFL_COMPILE_CACHE=off python timefit.py ROOT REC.csv"""
import sys, time, json, logging, re
root = sys.argv[1]; sys.path.insert(0, root)
import jax
cnt = [0, 0.0]
class H(logging.Handler):
    def emit(self, r):
        m = re.search(r"Finished XLA compilation of .* in ([0-9.e-]+) sec", r.getMessage())
        if m: cnt[0] += 1; cnt[1] += float(m.group(1))
jax.config.update("jax_log_compiles", True)
lg = logging.getLogger("jax._src.dispatch"); lg.addHandler(H()); lg.setLevel(logging.DEBUG); lg.propagate = False
for n in ("jax._src.interpreters.pxla", "jax._src.compiler", "jax"): logging.getLogger(n).propagate = False
import numpy as np
import smafl_jax as sj
assert sj.__file__.startswith(root), sj.__file__
from smafl_jax.report import fit_record
t0 = time.time()
model, doc, _ = fit_record(sj.load_record(sys.argv[2]))
wall = time.time() - t0
rec = sj.load_record(sys.argv[2])
yh = np.asarray(sj.simulate(model, rec.u, rec.dt))
print(json.dumps({"root": root, "wall": round(wall, 1), "compiles": cnt[0], "compile_s": round(cnt[1], 1), "rmse": float(np.sqrt(np.mean((yh - rec.y) ** 2))), "chosen": doc["settings"].get("structure_choice", {}).get("chosen"), "val": doc.get("metrics", {}).get("validation")}))
