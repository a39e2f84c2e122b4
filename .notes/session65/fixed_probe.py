"""Probe: candidate fitted with the base held (effect-only) vs the joint fit. python fixed_probe.py TRUTH SEED [NAME]"""
import sys, tempfile, json
import numpy as np, jax.numpy as jnp, equinox as eqx
sys.path.insert(0, "experiments")
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D
from smafl_jax.effects import ExtendedModel
truth, seed = sys.argv[1], int(sys.argv[2])
name = sys.argv[3] if len(sys.argv) > 3 else truth
got = {}
orig = D._from_refined_base_too
def patched(m, info, base, cand_start, nm, split, verbose=False):
    got['start_' + nm] = m
    out = orig(m, info, base, cand_start, nm, split, verbose)
    got[nm] = out[0]; got['__base'] = base
    return out
D._from_refined_base_too = patched
with tempfile.TemporaryDirectory() as tmp:
    path, case = ie.write_effect_record(tmp, truth, seed)
    rec = sj.load_record(path)
    res = D.diagnose(rec, effects=[name], refit=False, verbose=False, rule="calibrated", n_null=2, unexplained=False)
split = res.split; base = got['__base']; noise = case['noise_rms_measured']
print("case", {k: case[k] for k in ('drive','rate_hz','minutes','start','variant','effect_params','effect_over_noise')})
def rep(lab, m):
    tr, te = D._metrics_pair(m, split)
    print(f"{lab:34s} train {tr['rmse']/noise:.2f} held {te['rmse']/noise:.2f}")
rep("base", base)
rep("joint (diagnose)", got[name])
ctx = D._context(split)
start = ExtendedModel(ExtendedModel.of(base).base, tuple(ExtendedModel.of(base).effects) + (D._effect_grid(name, ctx)[0],))
lay_all = D._phi_layout(start, ctx)
lay = [l for l in lay_all if l[0] == name]
print("effect params", [(l[1]) for l in lay])
from scipy.optimize import minimize
def sse_fixed(phi):
    return D._train_sse(D._set_phi(start, lay, phi), split.train)
def sse_prof(phi):
    return D.profile_gains(D._set_phi(start, lay, phi), split.train)[1]
best = None
for c in D._effect_grid(name, ctx):
    m0 = ExtendedModel(start.base, tuple(ExtendedModel.of(base).effects) + (c,))
    p0 = D._get_phi(m0, lay_all)[-len(lay):]
    for f, lab in ((sse_fixed, 'fixed'), (sse_prof, 'prof')):
        r = minimize(f, p0, method='Nelder-Mead', options=dict(maxiter=200 * len(lay), xatol=1e-4, fatol=1e-12))
        if best is None or True:
            m = D._set_phi(start, lay, r.x)
            if lab == 'prof':
                m = D.profile_gains(m, split.train)[0]
            got.setdefault(lab, []).append((r.fun, m, r.x))
for lab in ('fixed', 'prof'):
    f, m, x = min(got[lab], key=lambda t: t[0])
    rep(f"effect-only ({lab}) x={np.round(x,4)}", m)
    print("   ", D._effect_params(m.get(name)))
    mr = D.refine_model(m, split)
    rep(f"  then refined", mr)
print("--- null-space share on the main split")
for lab, m in (("base", base), ("joint", got[name])):
    print(lab, "undetermined", round(D.fold_undetermined(m, split), 3))
pb = D.profile_gains(base, split.train)[0]
rep("base re-profiled (BVLS)", pb)
print("base re-profiled undetermined", round(D.fold_undetermined(pb, split), 3))
# condition of the training design, column-scaled
A, _, _ = D._design(base, split.train)
sc = np.sqrt((A**2).sum(0)); sc[sc == 0] = 1
sv = np.linalg.svd(A / sc, compute_uv=False)
print("design cols", A.shape[1], "sv ratio min/max %.2e" % (sv[-1] / sv[0]), "n < 1e-9:", int((sv < 1e-9 * sv[0]).sum()), "n < 1e-6:", int((sv < 1e-6 * sv[0]).sum()))
