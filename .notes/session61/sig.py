"""Which _solve_optx calls compile: the signature that filter_jit keys on, per call."""
import sys, tempfile, time, threading
from pathlib import Path
root = Path(sys.argv[1]).resolve()
sys.path.insert(0, str(root)); sys.path.insert(0, str(root / "tests"))
import indep_plant, jax, equinox as eqx, numpy as np
import smafl_jax as sj
from smafl_jax.identify import _fit
from smafl_jax.report import fit_record
orig = _fit._solve_optx
SEEN = {}
LOCK = threading.Lock()
def sig(x):
    leaves, tdef = jax.tree_util.tree_flatten(x)
    return (str(tdef), tuple((np.shape(l), str(getattr(l, 'dtype', type(l)))) if eqx.is_array(l) else repr(l)[:80] for l in leaves))
def wrap(solver, raw_train, static, args, max_steps, count=True):
    s = (sig(solver), sig(raw_train), sig(static), sig(args), max_steps, count)
    with LOCK:
        new = s not in SEEN
        SEEN.setdefault(s, 0); SEEN[s] += 1
        idx = list(SEEN).index(s)
    t0 = time.perf_counter()
    out = orig(solver, raw_train, static, args, max_steps, count)
    jax.block_until_ready(out)
    print(f"solve sig#{idx} new={new} {time.perf_counter()-t0:.1f}s args={[tuple(np.shape(a) for a in r) for r in args]} max_steps={max_steps} ntrain={len(jax.tree_util.tree_leaves(raw_train))}", flush=True)
    return out
_fit._solve_optx = wrap
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=float(sys.argv[2]) if len(sys.argv)>2 else 20.0, start="cold")
with tempfile.TemporaryDirectory() as tmp:
    p = Path(tmp) / "rec.csv"; indep_plant.write_csv(p, r); rec = sj.load_record(p)
    t0 = time.perf_counter(); _, doc, _ = fit_record(rec)
    print("TOTAL", time.perf_counter() - t0)
sigs = list(SEEN)
import difflib
for i, s in enumerate(sigs):
    print(f"=== sig#{i} calls {SEEN[s]}")
    if i:
        for name, a, b in zip(("solver","raw","static","args","max","count"), sigs[0], s):
            if a != b: 
                print("  differs in", name)
                if name in ("raw","static"):
                    d = [l for l in difflib.unified_diff(str(a).split(','), str(b).split(','), lineterm='', n=0) if not l.startswith(('---','+++','@@'))]
                    print("   ", d[:12])
