"""Session 63: the fold test's re-profiled gains, plain vs anchored to the main-split fit (ridge toward its gains).
Runs the diagnosis of one independent record (experiments/indep_effects.py); at each candidate's fold test prints the
fold gains with the gains re-profiled (a) as now, (b..) with a ridge of strength R toward the candidate's / base's own
main-split gains.  python fold_anchor_probe.py TRUTH SEED [RIDGE ...]"""
import sys, tempfile
import numpy as np
sys.path.insert(0, "experiments")
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D
from smafl_jax.identify.linear import solve

truth, seed = sys.argv[1], int(sys.argv[2])
ridges = [float(r) for r in sys.argv[3:]] or [1e-4, 1e-3, 1e-2]


def anchored_profile(model, segs, ridge):
    A, y, added = D._design(model, segs)
    theta0 = np.asarray(model.hysteresis.linear_weights(), float)
    for name, field in added:
        theta0 = np.r_[theta0, float(getattr(model.get(name), field))]
    nonneg = model.hysteresis.nonnegative_columns()
    nonneg = np.r_[nonneg, np.zeros(len(added), bool)]
    lower = np.where(nonneg, -theta0, -np.inf)
    d = solve(A, y - A @ theta0, lower=lower, ridge=ridge, method="bvls").x
    theta = theta0 + np.asarray(d)
    for name, field in reversed(added):
        import equinox as eqx, jax.numpy as jnp
        model = eqx.tree_at(lambda mm: getattr(mm.get(name), field), model, jnp.asarray(theta[-1]))
        theta = theta[:-1]
    return model.with_hysteresis(model.hysteresis.with_linear_weights(theta))


orig = D.calibration_gates


def patched(record, split, current, current_te, name, cand, cand_te, **kw):
    out = orig(record, split, current, current_te, name, cand, cand_te, **kw)
    if "folds" in out or out["gates"].get("max_error"):
        fs_all = D.fold_splits(record, kw.get("n_folds", 3))
        rows = {"now": [round(f["gain"], 3) for f in out.get("folds", [])]}
        for r in ridges:
            g = []
            for fs in fs_all:
                b = D._held(anchored_profile(current, fs.train, r), fs)["rmse"]
                c = D._held(anchored_profile(cand, fs.train, r), fs)["rmse"]
                g.append(round(1 - c / b, 3))
            rows[f"ridge {r:g}"] = g
        print(f"PROBE {truth} s{seed} {name}: gain {out['gain']:.3f} {rows} accepted={out['accepted']} reason={out.get('reason')}", flush=True)
    return out


D.calibration_gates = patched
with tempfile.TemporaryDirectory() as tmp:
    path, case = ie.write_effect_record(tmp, truth, seed)
    rec = sj.load_record(path)
    res = D.diagnose(rec, refit=False, verbose=False, rule="calibrated", n_null=8, unexplained=False).report
    print(f"PROBE {truth} s{seed} selected {res['selected']} base held-out {res['base']['heldout_rmse'] / case['noise_rms_measured']:.2f}x")
