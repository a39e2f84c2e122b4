"""At each fit's nonlinear params: held-out error with gains by BVLS (fit), unconstrained ridge (prior sd s x range)."""
import sys, glob, json, numpy as np, smafl_jax as sj
sd = 0.005
for D in sorted(glob.glob("/tmp/hc[AB]/s*/")):
    try:
        model, _ = sj.load_model_file(f"{D}/fit/fit.json")
    except Exception as e:
        continue
    rec = sj.load_record(f"{D}/record.csv"); n = len(sj.load_record(f"{D}/train70.csv"))
    if not hasattr(model, "features") or model.hysteresis is None:
        print(D, "no features"); continue
    A = np.asarray(model.features(rec.u, rec.dt)); y = np.asarray(rec.y)
    At, yt = A[:n], y[:n]; yr = np.ptp(yt)
    c = np.sqrt(np.mean(At**2, 0)) + 1e-12
    out = {}
    e = np.asarray(sj.simulate(model, rec.u, rec.dt)) - y
    out["fit"] = np.sqrt(np.mean(e[n:]**2))/sd
    r0 = np.linalg.lstsq(At, yt, rcond=None)[0]; sig2 = np.mean((At @ r0 - yt)**2)
    for s in (10.0, 1.0, 0.3):
        tau = s * yr * np.ones(A.shape[1])
        M = At.T @ At / sig2 + np.diag(1 / tau**2)
        w = np.linalg.solve(M, At.T @ yt / sig2)
        e = A @ w - y
        out[f"ridge{s}"] = np.sqrt(np.mean(e[n:]**2))/sd
    print(D.split("/")[-2][:40].ljust(42), " ".join(f"{k} {v:7.2f}" for k, v in out.items()), flush=True)
