"""Why one fold's re-profiled gains diverge: conditioning of the fold-training design. python fold_cond_probe.py TRUTH SEED NAME"""
import sys, tempfile
import numpy as np, jax.numpy as jnp
sys.path.insert(0, "experiments")
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D
from smafl_jax.identify.linear import solve
truth, seed, which = sys.argv[1], int(sys.argv[2]), sys.argv[3]; WW = float(sys.argv[4])
orig = D.calibration_gates
def gcv_ridge(A, y, nonneg, lams):
    # ridge on column-normalised design, unconstrained GCV
    s = np.sqrt((A**2).sum(0)) + 1e-300
    An = A / s
    U, S, Vt = np.linalg.svd(An, full_matrices=False)
    uty = U.T @ y; n = len(y)
    out = []
    for lam in lams:
        f = S**2 / (S**2 + lam)
        r = y - U @ (f * uty)
        out.append((float(n * (r @ r) / (n - f.sum())**2), lam))
    return out
def patched(record, split, current, current_te, name, cand, cand_te, **kw):
    out = orig(record, split, current, current_te, name, cand, cand_te, **kw)
    if name == which and "folds" in out:
        for j, fs in enumerate(D.fold_splits(record, 3)):
            for lab, m in (("base", current), ("cand", cand)):
                A, y, added = D._design(m, fs.train)
                At, yt, _ = D._design(m, fs.test)
                nonneg = np.r_[m.hysteresis.nonnegative_columns(), np.zeros(len(added), bool)]
                s = np.sqrt((A**2).sum(0)) + 1e-300
                S = np.linalg.svd(A / s, compute_uv=False)
                th = D._bvls(A, y, nonneg)
                r_tr = np.sqrt(np.mean((A @ th - y)**2)); r_te = np.sqrt(np.mean((At @ th - yt)**2))
                res = [f"fold {j} {lab}: cond {S[0]/S[-1]:.3g} train {r_tr:.4g} test {r_te:.4g}"]
                for lam in (1e-8, 1e-6, 1e-4, 1e-2):
                    # bounded ridge on the normalised columns
                    Ar = np.vstack([A / s, np.sqrt(lam) * np.eye(A.shape[1])]); yr = np.r_[y, np.zeros(A.shape[1])]
                    thr = D._bvls(Ar, yr, nonneg) / s
                    res.append(f"lam {lam:g}: tr {np.sqrt(np.mean((A @ thr - y)**2)):.4g} te {np.sqrt(np.mean((At @ thr - yt)**2)):.4g}")
                U_, S_, Vt_ = np.linalg.svd(A / s, full_matrices=False)
                for rc in (1e-12, 1e-10, 1e-8, 1e-6):
                    V0 = Vt_[S_ < rc * S_[0]]
                    if len(V0) == 0:
                        res.append(f"rc {rc:g}: none"); continue
                    w = WW * S_[0]
                    Ar = np.vstack([A / s, w * V0]); yr = np.r_[y, np.zeros(len(V0))]
                    thr = D._bvls(Ar, yr, nonneg) / s
                    res.append(f"rc {rc:g} ({len(V0)}): tr {np.sqrt(np.mean((A @ thr - y)**2)):.4g} te {np.sqrt(np.mean((At @ thr - yt)**2)):.4g}")
                if j == 0:
                    for v in V0[:0] if False else Vt_[S_ < 1e-10 * S_[0]]:
                        top = np.argsort(-np.abs(v))[:4]
                        print("   null", lab, [(int(c), round(float(v[c]), 3)) for c in top], flush=True)
                    ptr = np.ptp(A, 0); pte = np.ptp(At, 0)
                    print("   ptp train", np.round(ptr, 4).tolist(), "\n   ptp test ", np.round(pte, 4).tolist(), "\n   nonneg", nonneg.astype(int).tolist(), flush=True)
                zc = np.flatnonzero(np.ptp(A, 0) < 1e-9 * (np.abs(A).max(0) + 1e-300))
                res.append(f"const cols train {zc.tolist()} of {A.shape[1]}; test ptp {[float(np.ptp(At[:, c])) for c in zc]}")
                print(" | ".join(res), flush=True)
    return out
D.calibration_gates = patched
with tempfile.TemporaryDirectory() as tmp:
    path, case = ie.write_effect_record(tmp, truth, seed)
    rec = sj.load_record(path)
    res = D.diagnose(rec, effects=[which], refit=False, verbose=False, rule="calibrated", n_null=2, unexplained=False).report
