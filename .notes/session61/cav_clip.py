import sys, numpy as np
sys.path.insert(0, "/tmp/s61")
import smafl_jax as sj
from clip_probe_lib import sim_clipped
from smafl_jax.identify._baselines import fit_static_poly
D = "/work/shared/data/real/"
names = [f"cavatappi_pneumatic_200g_{s}.csv" for s in ("s1_t1", "s1_t2", "s2_t1", "s3_t1")]
recs = {n: sj.load_record(D + n, input="pressure", output="displacement_mm", resample=0.01) for n in names}
for n, r in recs.items(): print(n, len(r), f"u [{r.u.min():.3g},{r.u.max():.3g}] y [{np.nanmin(r.y):.3g},{np.nanmax(r.y):.3g}]")
rs = []
for test in names:
    train = [recs[n] for n in names if n != test]
    model, doc, _ = sj.fit_records(train, split="none")
    R = recs[test]; ok = np.isfinite(R.y) & R.measured
    lo = min(r.u.min() for r in train); hi = max(r.u.max() for r in train)
    e = lambda p: float(np.sqrt(np.mean((np.asarray(p)[ok] - R.y[ok]) ** 2)))
    a = e(sj.simulate(model, R.u, R.dt)); yb = sim_clipped(model, R.u, R.dt, (lo, hi)); b = e(yb) if yb is not None else float("nan")
    c = e(fit_static_poly(train, order=3).predict(R.u, R.dt))
    out = float(np.mean((R.u < lo) | (R.u > hi)))
    print(f"{test} {type(model).__name__} out {out:.3f} model {a:.4g} held {b:.4g} cubic {c:.4g}", flush=True)
