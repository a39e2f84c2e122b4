"""Session 71 probe: Nelder-Mead of the delay candidate from every grid start (fit_extended refines only the best)."""
import sys, time, tempfile
sys.path.insert(0, "experiments")
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D  # private: probe of the candidate fit
from smafl_jax.effects import ExtendedModel
import jax.numpy as jnp

seed = int(sys.argv[1]); kind = sys.argv[2]; name = sys.argv[3] if len(sys.argv) > 3 else "delay"
truth = sys.argv[4] if len(sys.argv) > 4 else name
path, case = ie.write_effect_record(tempfile.mkdtemp(), truth, seed)
print(name, seed, case.get("effect_params"), case["drive"], case["n"])
rec = sj.load_record(path)
base0, _ = D.choose_base(rec)
split = D.make_split(rec, kind=kind)
t = time.time()
base0, scr = D.screened_base(base0, split, False)
base, info = D.fit_extended(base0, [], split)
base, cand_start, _ = D.refined_base(base, base0, split, False)
base, _ = D.converged_base(base, split, False)
btr, bte = D._metrics_pair(base, split)
print(f"split {split.kind} base train {btr['rmse']:.5f} held {bte['rmse']:.5f}  ({time.time()-t:.0f} s)")
ctx = D._context(split)
b = cand_start.base if isinstance(cand_start, ExtendedModel) else cand_start
m, info = D.fit_extended(cand_start, [name], split)
tr, te = D._metrics_pair(m, split)
print(f"default fit: {D._effect_params(m.get(name))} train sse {info['train_sse']:.5g} rmse {tr['rmse']:.5f} held {te['rmse']:.5f}")
for st in D._effect_grid(name, ctx):
    raw = D.profile_gains(ExtendedModel(b, (st,)), split.train)[1]
    m2, info2 = D.fit_extended(ExtendedModel(b, (st,)), [], split)
    tr2, te2 = D._metrics_pair(m2, split)
    print(f"  from {D._effect_params(st)} raw sse {raw:.5g}: {D._effect_params(m2.get(name))} train sse {info2['train_sse']:.5g} rmse {tr2['rmse']:.5f} held {te2['rmse']:.5f}")
