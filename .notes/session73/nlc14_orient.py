import sys, time
import numpy as np
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D
from smafl_jax.identify._choose import screen_start
from smafl_jax.models._hysteresis import hysteresis_of
rec = sj.load_record(sys.argv[1])
base0, _ = D.choose_base(rec)
split = D.make_split(rec, holdout_residue=None, kind="auto") if False else D.make_split(rec, kind="auto")
data = [(s.u, s.y, s.dt) for s in split.train]
weights = [s.mask.astype(float) for s in split.train]
model, table, info = screen_start(base0, data, weights, val_weights=None, memory="rule")
print("chosen orientation", hysteresis_of(model).orientation, "sees", model.sees)
rows = sorted(table, key=lambda r: r["loss"])[:8] if isinstance(table, list) else table
for r in rows: print({k: r[k] for k in r if k != "seconds"})
alts = (info or {}).get("alternatives") or []
print("alternatives:", len(alts), [(hysteresis_of(a).orientation, a.sees) for a in alts])
noise = sj.noise_floor([rec])["sd"] if hasattr(sj, "noise_floor") else None
for tag, m0 in [("chosen", model)] + [(f"alt{i}", a) for i, a in enumerate(alts)]:
    t = time.time()
    b, _ = D.fit_extended(m0, [], split, k1_grid=None)
    b2, _, doc = D.refined_base(b, m0, split)
    print(tag, "orient", hysteresis_of(m0).orientation, "fit_extended train sse %.4g held %.4g" % (D._train_sse(b, split.train), D._held(b, split)["rmse"]),
          "| refined (%s) train sse %.4g held %.4g" % (doc["chosen"], D._train_sse(b2, split.train), D._held(b2, split)["rmse"]),
          "train BICs", {k: round(v["bic"], 1) for k, v in doc["train"].items()}, "%.0f s" % (time.time() - t), flush=True)
