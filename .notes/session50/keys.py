import sys, time, tempfile, collections, threading
from pathlib import Path
sys.path.insert(0, "tests")
import jax, numpy as np, equinox as eqx
import indep_plant
import smafl_jax as sj
import smafl_jax.identify._fit as F
from smafl_jax.report import fit_record
seen = {}
lock = threading.Lock()
def keyof(*a):
    leaves, td = jax.tree_util.tree_flatten(a)
    return (str(td), tuple((x.shape, str(x.dtype)) if hasattr(x, "shape") else repr(x) for x in leaves))
orig = F._solve_optx
def wrapped(solver, raw_train, static, args, max_steps, count=True):
    k = keyof(solver, raw_train, static, args, max_steps, count)
    with lock:
        if k not in seen:
            seen[k] = len(seen)
            t = str(k[0])
            import re
            desc = re.findall(r"Cascade\[\(Missing, '(\w+)'|JouleThermal\[\(Missing, '(\w+)'|EUPI\[\(Missing, '(\w+)', '\w+', (-?1)\)\]|Preisach\w*\[[^\]]*\]", t)
            print(f"NEW solve key {len(seen)}: max_steps={max_steps} args_len={[np.shape(x[0]) for x in args]} treedef_len={len(t)} {desc[:6]} rawtrain={jax.tree_util.tree_structure(raw_train).num_leaves}", flush=True)
    return orig(solver, raw_train, static, args, max_steps, count)
F._solve_optx = wrapped
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
p = Path(tempfile.mkdtemp()) / "rec.csv"
indep_plant.write_csv(p, r)
fit_record(sj.load_record(p), model=sys.argv[1] if len(sys.argv) > 1 else "auto")
