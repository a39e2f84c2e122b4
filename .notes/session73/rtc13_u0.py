import pickle, numpy as np, equinox as eqx, jax.numpy as jnp
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D
from smafl_jax.identify._fit import default_trainable
d = pickle.load(open('/tmp/s73/probe/rtc13.pkl', 'rb'))
b, split = d.base, d.split
print("trainable u0:", default_trainable(b).thermal.u0)
def show(tag, m):
    print(tag, "u0 %.4g k1 %.4g k2 %.4g" % (float(m.thermal.u0), float(m.thermal.k1), float(m.thermal.k2)),
          "train sse %.4f held %.5f" % (D._train_sse(m, split.train), D._held(m, split)["rmse"]))
show("base", b)
for u0 in (0.01, 0.5, 1.0, 2.0):
    m = eqx.tree_at(lambda m: m.thermal.u0, b, jnp.asarray(u0))
    show(f"u0={u0} as is", m)
    m2 = D.refine_model(m, split)
    show(f"u0={u0} refined", m2)
    m3 = D.refine_model(D.fit_extended(m, [], split)[0], split)
    show(f"u0={u0} varpro+refined", m3)
