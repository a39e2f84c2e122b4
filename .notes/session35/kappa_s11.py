import sys, numpy as np
import smafl_jax as sj
tag = sys.argv[1]
d = np.load(f"/tmp/s35_{tag}.npz"); h0 = int(d["h0"])
rec = sj.load_record(f"/tmp/s35_{tag}.csv"); r70 = sj.load_record(f"/tmp/s35_{tag}_70.csv")
def score(m):
    yh = np.asarray(sj.simulate(m, rec.u, rec.dt)); e = yh - rec.y
    return "train %.3f held %.3f" % (np.sqrt(np.mean(e[:h0]**2))/0.005, np.sqrt(np.mean(e[h0:]**2))/0.005)
for mname in sys.argv[2:]:
    mf = sj.load_model(mname)
    for k in (None, 1.0, 0.3, 0.1, 0.03, 0.01, 0.003):
        m = sj.fit(mf, r70, solver=None, init="linear", gain_prior=k).model
        print(mname, k, score(m))
