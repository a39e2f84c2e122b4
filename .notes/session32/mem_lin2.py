import sys
sys.path.insert(0, sys.argv[1])
import jax, jax.numpy as jnp, numpy as np, equinox as eqx, dataclasses
import smafl_jax as sj
from smafl_jax import GaussianPreisach
n = int(sys.argv[2])
h = GaussianPreisach.from_range(0.0, 1.0).with_linear_weights(jnp.array([1.0, 0.1, 0.0]))
m = sj.Cascade(thermal=sj.JouleThermal(k1=jnp.asarray(0.2), k2=jnp.asarray(0.05)), hysteresis=h)
u = jnp.asarray(2.0 + 1.5 * np.sin(np.linspace(0, 60, n)))
def f(p):
    mm = eqx.tree_at(lambda q: (q.thermal.k1, q.hysteresis.centre), m, (p[0], p[1]))
    return mm.simulate(u, 0.1)
def jac(p):
    y, lin = jax.linearize(f, p)
    return jax.vmap(lin)(jnp.eye(2)).T
ma = jax.jit(jac).lower(jnp.array([0.2, 0.5])).compile().memory_analysis()
print(n, 'relays', h.n_relays, 'temp bytes per sample per relay %.1f' % (ma.temp_size_in_bytes / n / h.n_relays))
