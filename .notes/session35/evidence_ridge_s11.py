"""Evidence-chosen ridge (type-II ML) on the gains vs BVLS + kappa 1, at fixed nonlinear params."""
import sys, numpy as np, scipy.optimize as so, smafl_jax as sj
tag = sys.argv[1]; mname = sys.argv[2]
d = np.load(f"/tmp/s35_{tag}.npz"); h0 = int(d["h0"])
rec = sj.load_record(f"/tmp/s35_{tag}.csv")
m = sj.load_model(mname)
A = np.asarray(m.features(rec.u, rec.dt)); y = np.asarray(rec.y); sd = 0.005
h = m.hysteresis; nn = np.asarray(h.nonnegative_columns(), bool)
At, yt = A[:h0], y[:h0]
yr = np.ptp(yt)
def score(w):
    e = A @ w - y; return np.sqrt(np.mean(e[:h0]**2))/sd, np.sqrt(np.mean(e[h0:]**2))/sd
# unpenalised lstsq
w0 = np.linalg.lstsq(At, yt, rcond=None)[0]; print("lstsq", score(w0))
sig2 = np.mean((At @ w0 - yt)**2)
# scaled columns
c = np.sqrt(np.mean(At**2, 0)) + 1e-12; As = At / c
U, s, Vt = np.linalg.svd(As, full_matrices=False)
def evidence(kappa, big=10.0):
    tau = np.where(nn, kappa, big) * yr * c   # prior sd of scaled weights
    # marginal: y ~ N(0, sig2 I + As T As^T); use Woodbury with p x p
    T = np.diag(tau**2)
    M = np.diag(1/tau**2) + As.T @ As / sig2
    L = np.linalg.cholesky(M)
    b = As.T @ yt / sig2
    z = np.linalg.solve(L, b)
    n = len(yt)
    quad = yt @ yt / sig2 - z @ z
    logdet = n*np.log(sig2) + 2*np.sum(np.log(np.diag(L))) + np.sum(np.log(tau**2))
    mean = np.linalg.solve(L.T, z) / c
    return -0.5*(quad + logdet), mean
for k in (10, 3, 1, 0.3, 0.1, 0.03, 0.01, 0.003, 0.001):
    ev, w = evidence(k)
    print(f"kappa {k:6}: log evidence {ev:12.2f} ridge-mean train/held {score(w)[0]:.3f} {score(w)[1]:.3f}")
# separate kappa per field group? print nonneg count
print("p", A.shape[1], "nonneg", nn.sum())
print("--- predictive band of the gains' posterior (fixed nonlinear params) on held-out")
Ah = A[h0:] / c
for k in (10, 1, 0.3):
    tau = np.where(nn, k, 10.0) * yr * c
    M = np.diag(1/tau**2) + As.T @ As / sig2
    Minv = np.linalg.inv(M)
    ev, w = evidence(k)
    sdp = np.sqrt(np.einsum("ij,jk,ik->i", Ah, Minv, Ah))
    e = (A @ w - y)[h0:]
    z = e / np.sqrt(sdp**2 + sig2)
    print(f"kappa {k}: held RMSE {np.sqrt(np.mean(e**2))/sd:.2f}x noise, median band sd {np.median(sdp)/sd:.2f}x noise, max {sdp.max()/sd:.2f}x; 95% coverage {np.mean(np.abs(z) < 1.96):.3f}")
