import sys, time, tempfile, collections, threading, re
from pathlib import Path
sys.path.insert(0, "tests")
import jax, numpy as np, equinox as eqx
import indep_plant
import smafl_jax as sj
import smafl_jax.identify._fit as F
import smafl_jax.identify.varpro as V
from smafl_jax.report import fit_record
lock = threading.Lock()
seen = collections.defaultdict(dict)
def desc(tree):
    dyn, st = eqx.partition(tree, eqx.is_array)
    leaves, td = jax.tree_util.tree_flatten(dyn)
    shapes = tuple(x.shape for x in leaves)
    s = str(jax.tree_util.tree_structure(st)) + str(td)
    return s, shapes
def summarize(s):
    names = re.findall(r"(Cascade|JouleThermal|EUPI|Preisach\w*|GaussianPreisach)\[\(([^\]]{0,80})", s)
    return [f"{n}:{a[:60]}" for n, a in names[:4]]
def wrap(name, orig, mod, attr):
    def w(*a, **k):
        s, shapes = desc(a)
        key = (s, shapes)
        with lock:
            d = seen[name]
            if key not in d:
                d[key] = len(d)
                arrs = [sh for sh in shapes if len(sh) >= 1 and max(sh) > 500]
                print(f"NEW {name} #{len(d)} big={arrs[:3]} nleaves={len(shapes)} {summarize(s)}", flush=True)
        return orig(*a, **k)
    setattr(mod, attr, w)
import smafl_jax.identify._choose as C, smafl_jax.identify._memory_search as M
for mod in (F, C, M):
    if hasattr(mod, "_features"): wrap("_features", F._features, mod, "_features")
    if hasattr(mod, "_residuals_jit"): wrap("_residuals", F._residuals_jit, mod, "_residuals_jit")
wrap("_batch_design", V._batch_design_jit, V, "_batch_design_jit")
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
p = Path(tempfile.mkdtemp()) / "rec.csv"
indep_plant.write_csv(p, r)
t0 = time.time()
fit_record(sj.load_record(p), model=sys.argv[1] if len(sys.argv) > 1 else "auto")
print("total", time.time() - t0)
