"""Session 27 probe (plain numpy, plant A's own x_h): how much of the Preisach plane's state in the held-out part is NOT
a linear combination of the training part's relay states (32-level relay grid; per held-out sample the squared residual
of its state vector projected on the training states' row space, per relay).  Idea: a held-out error that no fit of the
training part can avoid.  Result: it does not separate the failing matrix cells (PWM cold s11: 2.9 % mean, held-out 14x;
multisine cold s17: 10.9 %, held-out 1.02x).  Run from the repo root:
    python .notes/session27/preisach_plane_identifiability.py experiments/results/stall_session26/matrix_new_seeds_7_11_13.json
"""
import sys, json, copy, numpy as np
sys.path.insert(0, "/work/main/tests")
import indep_plant as ip

def relay_states(x, L):
    lo, hi = x.min(), x.max()
    lev = np.linspace(lo, hi, L)
    a, b = np.meshgrid(lev, lev, indexing="ij")
    keep = a > b
    a, b = a[keep], b[keep]
    s = (a <= x[0]).astype(np.int8)  # descended-like start: relays on below x0
    S = np.empty((len(x), a.size), np.int8)
    for t, xt in enumerate(x):
        s = np.where(xt >= a, 1, np.where(xt <= b, 0, s)).astype(np.int8)
        S[t] = s
    return S

def unidentified(x, h0, L=32):
    S = relay_states(x, L).astype(float)
    tr, te = S[:h0], S[h0:]
    U = np.unique(tr, axis=0)
    U = np.c_[U, np.ones(len(U))]
    _, sv, Vt = np.linalg.svd(U, full_matrices=False)
    r = int(np.sum(sv > 1e-8 * sv[0]))
    V = Vt[:r].T
    T, inv = np.unique(te, axis=0, return_inverse=True)
    T1 = np.c_[T, np.ones(len(T))]
    res = T1 - (T1 @ V) @ V.T
    frac = np.sum(res**2, axis=1) / S.shape[1]
    return frac[inv.ravel()]

rows = []
for f in sys.argv[1:]:
    rows += json.load(open(f))
for row in rows:
    kw = ip.MATRIX_CELLS[row["cell"]]
    rec = ip.make_record(row["seed"], minutes=10, **kw)
    tr = copy.deepcopy(rec["truth"]); tr["effect"] = None
    x = ip._core(tr, rec["u"], rec["dt"], upto="x")["x_h"]
    # decimate for speed
    step = max(1, len(x) // 6000)
    xs = x[::step]; h0 = rec["heldout_start"] // step
    fr = unidentified(xs, h0)
    print(f"{row['cell']:30s} s{row['seed']:<3d} held {row['held']:6.2f}  unident mean {100*fr.mean():6.2f}%  p90 {100*np.quantile(fr,0.9):6.2f}%  max {100*fr.max():6.2f}%  frac>1% {np.mean(fr>0.01):.2f}", flush=True)
