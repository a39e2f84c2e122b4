"""Per fold and candidate: how much of the held-out block's design lies in directions the fold's training leaves
undetermined.  python fold_info_probe.py TRUTH SEED"""
import sys, tempfile
import numpy as np
sys.path.insert(0, "experiments")
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D
truth, seed = sys.argv[1], int(sys.argv[2])
orig = D.calibration_gates
def info(m, fs):
    A, y, added = D._design(m, fs.train); At, yt, _ = D._design(m, fs.test)
    nonneg = np.r_[m.hysteresis.nonnegative_columns(), np.zeros(len(added), bool)]
    th = D._bvls(A, y, nonneg)
    s = np.sqrt((A**2).sum(0)); s[s == 0] = 1.0
    U, S, Vt = np.linalg.svd(A / s, full_matrices=False)
    Bt = At / s
    out = []
    for rc in (1e-12, 1e-9, 1e-6):
        V0 = Vt[S < rc * S[0]]
        p0 = Bt @ (V0.T @ (V0 @ (s * th))) if len(V0) else np.zeros(len(yt))
        out.append(float(np.sqrt(np.mean(p0**2)) / np.sqrt(np.mean((A @ th - y)**2))))
    return S[0] / S[-1], out
def patched(record, split, current, current_te, name, cand, cand_te, **kw):
    out = orig(record, split, current, current_te, name, cand, cand_te, **kw)
    if "folds" in out:
        for j, (fs, f) in enumerate(zip(D.fold_splits(record, 3), out["folds"])):
            cb, eb = info(D.profile_gains(current, fs.train)[0], fs)
            cc, ec = info(D.profile_gains(cand, fs.train)[0], fs)
            print(f"INFO {truth} s{seed} {name} fold {j} gain {f['gain']:+.3f} base cond {cb:.2g} frac {['%.1e' % x for x in eb]} cand cond {cc:.2g} frac {['%.1e' % x for x in ec]}", flush=True)
    return out
D.calibration_gates = patched
with tempfile.TemporaryDirectory() as tmp:
    path, case = ie.write_effect_record(tmp, truth, seed)
    rec = sj.load_record(path)
    res = D.diagnose(rec, effects=sys.argv[3:] or None, refit=False, verbose=False, rule="calibrated", n_null=2, unexplained=False).report
    print(f"INFO {truth} s{seed} selected {res['selected']}")
