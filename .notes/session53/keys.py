import sys, time, tempfile, json
from pathlib import Path
sys.path.insert(0, "tests")
import jax, equinox as eqx, numpy as np
import indep_plant
import smafl_jax as sj
from smafl_jax.identify import _fit
from smafl_jax.report import fit_record
seen = {}
def summ(tree):
    leaves, td = jax.tree_util.tree_flatten(tree)
    return str(td)[:100000], tuple((getattr(l, "shape", None), str(getattr(l, "dtype", type(l).__name__))) for l in leaves)
orig = _fit._solve_optx
def wrap(solver, raw_train, static, args, max_steps, count=True):
    key = (summ((solver, raw_train, static, args, max_steps, count)))
    if key not in seen:
        seen[key] = len(seen)
        n = len(seen)
        print(f"NEW solve key #{n}: static td hash {hash(key[0])} shapes hash {hash(key[1])}", flush=True)
        # print model type + static fields
        print("   ", [getattr(x,'shape',None) for x in jax.tree_util.tree_leaves(args)][:6], max_steps, count, type(solver).__name__, flush=True)
        import difflib
        if len(seen) > 1:
            prev = [k for k in seen if seen[k] == 0][0]
            a = prev[0].replace(',', ',\n').splitlines(); b = key[0].replace(',', ',\n').splitlines()
            print("   TD diff vs #1:", [l for l in difflib.unified_diff(a, b, n=0, lineterm='')][2:40], flush=True)
            print("   shapes same as #1:", prev[1] == key[1], [ (x, y) for x, y in zip(prev[1], key[1]) if x != y][:5], len(prev[1]), len(key[1]), flush=True)
    return orig(solver, raw_train, static, args, max_steps, count)
_fit._solve_optx = wrap
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
p = Path(tempfile.mkdtemp()) / "rec.csv"
indep_plant.write_csv(p, r)
t0 = time.time()
fit_record(sj.load_record(p), model=sys.argv[1] if len(sys.argv) > 1 else "auto")
print("total", time.time() - t0)
