"""Probe: why a true effect holds out worse than the base. python drift_probe.py TRUTH SEED"""
import sys, tempfile, json
import numpy as np, jax.numpy as jnp
sys.path.insert(0, "experiments")
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D
truth, seed = sys.argv[1], int(sys.argv[2])
names = sys.argv[3:] or [truth]
got = {}
orig = D._from_refined_base_too
def patched(m, info, base, cand_start, name, split, verbose=False):
    out = orig(m, info, base, cand_start, name, split, verbose)
    got[name] = out[0]; got['__base'] = base
    return out
D._from_refined_base_too = patched
with tempfile.TemporaryDirectory() as tmp:
    path, case = ie.write_effect_record(tmp, truth, seed)
    rec = sj.load_record(path)
    truthdoc = json.load(open(str(path).replace('.csv', '.truth.json')))
    res = D.diagnose(rec, effects=names, refit=False, verbose=False, rule="calibrated", n_null=2, unexplained=False)
split = res.split; base = got['__base']
print("case", {k: case[k] for k in ('drive','rate_hz','minutes','start','variant','effect_params','effect_over_noise')})
print("noise", case['noise_rms_measured'])
def blocks(m):
    s = split.test[0]
    _, r = D.score(m, [s])
    k = np.array_split(r, 6)
    return [round(float(np.sqrt(np.mean(b**2)))/case['noise_rms_measured'], 2) for b in k]
for nm, m in [('base', base)] + [(n, got[n]) for n in names if n in got]:
    tr, te = D._metrics_pair(m, split)
    print(nm, "train/noise %.2f held/noise %.2f" % (tr['rmse']/case['noise_rms_measured'], te['rmse']/case['noise_rms_measured']), "held blocks", blocks(m))
    th = D.thermal_of(m)
    if th is not None: print("   thermal", {k: float(np.asarray(v)) for k, v in vars(th).items() if np.ndim(v)==0 and not isinstance(v, (str, bool, type(None)))})
    if nm != 'base': print("   effect", D._effect_params(m.get(nm)))
    # hysteresis input range train vs test
    for lab, segs in (('train', split.train), ('test', split.test)):
        xs = np.concatenate([np.asarray(m.hysteresis_input(jnp.asarray(s.u), jnp.asarray(s.dt)))[s.mask] for s in segs])
        print(f"   x {lab}: {xs.min():.4g}..{xs.max():.4g}")
