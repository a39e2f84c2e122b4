import sys, time, pickle, json
sys.path.insert(0, "/work/main")
import jax; jax.config.update("jax_enable_x64", True)
import equinox as eqx
import smafl_jax.identify._fit as FI
saved = pickle.load(open("/tmp/s53/lm_args.pkl", "rb"))
solver, raw, static, args, ms, count = saved[int(sys.argv[1])]
opts = json.loads(sys.argv[2])
fn = FI._solve_optx.__wrapped__
f = eqx.filter_jit(fn, compiler_options=opts) if opts else eqx.filter_jit(fn)
t=time.perf_counter(); low = f.lower(solver, raw, static, args, ms, False); t1=time.perf_counter(); c = low.compile(); t2=time.perf_counter()
out = f(solver, raw, static, args, ms, False); jax.block_until_ready(out); t3=time.perf_counter()
out = f(solver, raw, static, args, ms, False); jax.block_until_ready(out); t4=time.perf_counter()
print(f"{sys.argv[2]:50s} lower {t1-t:.2f} compile {t2-t1:.2f} call1 {t3-t2:.2f} call2 {t4-t3:.2f} steps {int(out[2])} loss {float(out[3]):.12g}")
