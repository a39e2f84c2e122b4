import sys, time, pickle
sys.path.insert(0, "/work/main")
import jax; jax.config.update("jax_enable_x64", True)
import equinox as eqx, optimistix as optx, jax.numpy as jnp
import smafl_jax.identify._fit as FI
saved = pickle.load(open("/tmp/s53/lm_args.pkl", "rb"))
which = int(sys.argv[1]) if len(sys.argv) > 1 else 0
solver, raw, static, args, ms, count = saved[which]
print(type(solver).__name__, [getattr(a, "shape", None) for a in jax.tree_util.tree_leaves(args)][:4])
from smafl_jax.identify._fit import _residuals, constrain
def resid(p): return _residuals(constrain(eqx.combine(p, static)), args)
t=time.perf_counter(); low = jax.jit(resid).lower(raw); c = low.compile(); print("residuals only: lower+compile", round(time.perf_counter()-t,2))
t=time.perf_counter(); low = jax.jit(lambda p: jax.jacfwd(resid)(p)).lower(raw); c = low.compile(); print("jacfwd: lower+compile", round(time.perf_counter()-t,2))
t=time.perf_counter(); low = jax.jit(lambda p, t_: jax.linearize(resid, p)[1](t_)).lower(raw, raw); c = low.compile(); print("linearize: lower+compile", round(time.perf_counter()-t,2))
f = FI._solve_optx
t=time.perf_counter(); low = f.lower(solver, raw, static, args, ms, False) if hasattr(f, "lower") else None
t1=time.perf_counter(); print("LM lower", round(t1-t,2))
c = low.compile(); print("LM compile", round(time.perf_counter()-t1,2))
t=time.perf_counter(); out = f(solver, raw, static, args, ms, False); jax.block_until_ready(out); print("LM call (traces+compiles again?)", round(time.perf_counter()-t,2), out[2])
t=time.perf_counter(); out = f(solver, raw, static, args, ms, False); jax.block_until_ready(out); print("LM call 2", round(time.perf_counter()-t,2), out[2])
