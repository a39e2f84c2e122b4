"""Capture the first LM solve of the benchmark fit; time lower/compile of variants."""
import sys, time, tempfile, pickle
from pathlib import Path
sys.path.insert(0, "tests")
import jax, jax.numpy as jnp, equinox as eqx, optimistix as optx, lineax as lx
import indep_plant
import smafl_jax as sj
import smafl_jax.identify._fit as F
from smafl_jax.report import fit_record
cap = {}
orig = F._solve_optx
class Stop(Exception): pass
def wrapped(*a, **k):
    cap["a"] = a; raise Stop
F._solve_optx = wrapped
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
p = Path(tempfile.mkdtemp()) / "rec.csv"
indep_plant.write_csv(p, r)
try:
    fit_record(sj.load_record(p), model="cascade", max_steps=300)
except Stop:
    F._solve_optx = orig
    pass
F._solve_optx = orig
solver, raw_train, static, args, max_steps = cap["a"]; count = False
print("solver", type(solver).__name__, type(getattr(solver, "solver", None)).__name__, "max_steps", max_steps, "count", count)
print("raw leaves", [x.shape for x in jax.tree_util.tree_leaves(raw_train)])
def timed(label, f, *a):
    t0 = time.perf_counter(); jax.block_until_ready(f(*a)); t1 = time.perf_counter(); jax.block_until_ready(f(*a)); t2 = time.perf_counter()
    print(f"{label:40s} first {t1-t0:6.2f} s again {t2-t1:6.2f} s -> compile ~{(t1-t0)-(t2-t1):6.2f}", flush=True)
which = sys.argv[1:] or ["base"]
def make(slv, opts=None):
    @eqx.filter_jit
    def go(raw_train, static, args):
        def fn(p, a):
            return F._residuals(F.constrain(eqx.combine(p, static)), a)
        sol = optx.least_squares(fn, slv, raw_train, args, max_steps=max_steps, throw=False, options=opts)
        return sol.value, sol.stats["num_steps"]
    return go
if "base" in which:
    timed("orig _solve_optx (count False)", F._solve_optx, solver, raw_train, static, args, max_steps, False)
if "lm" in which:
    timed("plain LM (no stall)", make(optx.LevenbergMarquardt(1e-8, 1e-8)), raw_train, static, args)
if "stall" in which:
    timed("stall LM", make(solver), raw_train, static, args)
if "res" in which:
    timed("residuals", eqx.filter_jit(F._residuals), F.constrain(eqx.combine(raw_train, static)), args)
if "jac" in which:
    @eqx.filter_jit
    def jac(raw_train, static, args):
        return jax.jacfwd(lambda p: F._residuals(F.constrain(eqx.combine(p, static)), args))(raw_train)
    timed("jacfwd", jac, raw_train, static, args)
if "gn" in which:
    timed("GaussNewton", make(optx.GaussNewton(1e-8, 1e-8)), raw_train, static, args)
if "chol" in which:
    timed("LM normal cholesky", make(optx.LevenbergMarquardt(1e-8, 1e-8, linear_solver=lx.Normal(lx.Cholesky()))), raw_train, static, args)
